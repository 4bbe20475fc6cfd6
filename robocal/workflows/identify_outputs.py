"""Output of `robocal identify dyn.yaml`: result.json, summary.txt, torque_validation.svg (measured vs
predicted torque per recorded joint on the validation window, robocal.viz.svg_torques) and, when it can be written, the URDF with
the identified inertias and friction; written atomically (robocal.io.output_folder.write_folder: an error leaves
no half-written folder). See docs/dynamics_tiago.md.
"""
from __future__ import annotations

import json
from pathlib import Path

import yaml

from robocal.dynamics.identify_log import MODELS
from robocal.dynamics.identified_model import SIDE_FILE
from robocal.workflows.identify import IdentifyResult
from robocal.workflows.identify_summary import LABELS, brief_summary_text, findings, summary_text
from robocal.workflows.identify_urdf import identified_urdf_entry, side_file, torque_units, urdf_of
from robocal.io.output_folder import write_folder
from robocal.viz.svg_torques import joint_torques



def result_dict(res: IdentifyResult, urdf: tuple | None = None) -> dict:
    """Everything the summary states, as JSON-ready values (units in the key names). urdf: `urdf_of(res)`
    when the caller has it already (it reads and edits the URDF file)."""
    proc, ols, fit = res.processed, res.ols, res.consistent
    bodies = res.model.names[1:]
    return {
        "config": res.config.source,
        **({"logged_motors": res.recorded, "transmission": res.channels.transmission.to_dict()}
           if res.channels is not None and res.channels.motors else {"recorded_joints": res.recorded}),
        "torque_units": torque_units(res),
        "signal_processing": {"choices": proc.choices, "cutoff_hz": proc.cutoff_hz, "grid_rate_hz": proc.fs_raw,
                              "decimation": proc.decimation, "velocity_check": proc.velocity_check},
        "logs": [{"name": p.part.name, "files": p.part.log.files, "train_s": [list(w) for w in p.part.train],
                  "validate_s": [list(w) for w in p.part.validate], "train_samples": int(p.train.sum()),
                  "validate_samples": int(p.check.sum())} for p in res.parts],
        "notes": res.notes,
        "findings": findings(res),
        "terms": {"per_joint": {j: list(t) for j, t in res.joint_terms.items()},
                  "delay_s": dict(zip(res.recorded, res.delays.tolist())),
                  "coulomb_width": dict(zip(res.joint_terms, res.coulomb_width.tolist()))
                  | (dict(zip(res.recorded, res.motor_width.tolist())) if res.motor_width.size else {}),
                  "tests": [vars(t) for t in res.term_tests]},
        "plausible_bounds": [{"joint": b.joint, "cad_mass_kg": b.cad_mass, "mass_range_kg": b.mass_range,
                              "ellipsoid_center_m": b.center.tolist(), "ellipsoid_semi_axes_m": b.semi_axes.tolist(),
                              "source": b.source} for b in res.bounds],
        "ols": {"names": ols.names, "values": ols.values.tolist(), "std": ols.std.tolist(),
                "condition_number": ols.condition, "rank": ols.selection.rank,
                "residual_rms_per_joint": ols.sigma.tolist(), "dropped": ols.selection.describe()},
        "consistent": {"prior_weight": fit.prior_weight, "prior_rule": res.prior.rule, "prior_grid": res.prior.grid,
                       "prior_scores": res.prior.scores, "prior_bound": res.prior.bound,
                       "prior_split": res.prior.split_fraction,
                       "solver_iterations": fit.iterations, "solver_status": fit.status, "converged": fit.converged,
                       "inertial": {b: p.tolist() for b, p in zip(bodies, fit.inertial.reshape(-1, 10))},
                       "extra": dict(zip(res.consistent_extra_names(), fit.extra.tolist())),
                       "mass_kg": dict(zip(bodies, fit.inertial[0::10].tolist())),
                       "mass_std_kg": dict(zip(bodies, res.mass_std().tolist())),
                       "std": res.consistent_std.tolist(),
                       "pseudo_inertia_min_eigenvalue": {b: v[0] for b, v in res.consistency.items()},
                       "physically_consistent": {b: v[1] for b, v in res.consistency.items()}},
        "validation_rmse": res.validation,
        "validation_torque_range": res.torque_range,
        "training_rms": res.training_rms,
        "consistent_vs_ols": res.within_noise,
        "constraint_costs_noise_units": [{"constraint": c.constraint, "cost": c.cost, "value_without": c.value_without}
                                         for c in res.constraint_costs],
        "constraint_costs_prior_weight": min(res.prior.grid),
        "external_force_rms_N": res.wrench_rms,
        "identified_urdf": identified_urdf_entry(urdf if urdf is not None else urdf_of(res)),
    }


def torque_figure(res: IdentifyResult) -> bytes:
    """SVG: measured and predicted torques per recorded joint on the validation window."""
    return joint_torques(res.curves["t"], res.curves["measured"], {LABELS[m]: res.curves[m] for m in MODELS},
                         [j.replace("_joint", "") for j in res.recorded], torque_units(res),
                         title="Held-out window: measured (low-pass filtered) vs predicted torque").encode()


def identification_files(res: IdentifyResult) -> tuple[dict[str, bytes], str]:
    """Every file of an identification folder, and the brief summary `robocal identify -q` prints."""
    urdf = urdf_of(res)
    d = result_dict(res, urdf)
    files = {"result.json": json.dumps(d, indent=1).encode(), "summary.txt": summary_text(res, d).encode()}
    name, data, _ = urdf
    if data is not None:
        files[name] = data
        files[SIDE_FILE] = yaml.safe_dump(side_file(res, name).to_dict(), sort_keys=False).encode()
    if res.curves:
        files["torque_validation.svg"] = torque_figure(res)
    return files, brief_summary_text(res, d)


def write_identification(res: IdentifyResult, out_dir: str | Path, force: bool = False) -> dict[str, Path]:
    return write_folder(out_dir, identification_files(res)[0], force=force)


