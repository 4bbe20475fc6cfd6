"""Output of `robocal identify dyn.yaml`: result.json, summary.txt, torque_validation.png (measured vs
predicted torque per recorded joint on the validation window) and, when it can be written, the URDF with
the identified inertias and friction; written atomically (robocal.io.output_folder.write_folder: an error leaves
no half-written folder). See docs/dynamics_tiago.md.
"""
from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import yaml

from robocal.dynamics.identify_log import MODELS
from robocal.dynamics.identified_model import SIDE_FILE, IdentifiedDynamics
from robocal.workflows.identify import IdentifyResult, effort_map_of
from robocal.workflows.identify_summary import LABELS, findings, summary_text
from robocal.dynamics.inertial import parameter_vector
from robocal.dynamics.urdf_inertials import identified_urdf
from robocal.io.output_folder import write_folder



def torque_units(res: IdentifyResult) -> list[str]:
    """N for a prismatic recorded joint, N m for a revolute one."""
    return ["N" if res.model.joints[res.model.getJointId(j)].shortname().startswith("JointModelP") else "N m"
            for j in res.recorded]


def urdf_of(res: IdentifyResult) -> tuple[str, bytes | None, list[str]]:
    """(file name, URDF bytes or None, remarks or why not): the input URDF carrying the consistent model's
    inertias (urdf_inertials.py); none when the solver stopped short."""
    name = f"{Path(res.config.urdf).stem}_identified.urdf"
    if not res.consistent.converged:
        return name, None, [f"the consistent fit's solver stopped short (status {res.consistent.status})"]
    friction: dict[str, dict[str, float]] = {}
    for joint, terms in joint_term_values(res).items():
        # URDF's <dynamics damping friction> holds one value each: an asymmetric pair's mean (the side file
        # has both)
        for kind in ("viscous", "coulomb"):
            pair = [terms[f"{kind}_pos"], terms[f"{kind}_neg"]] if f"{kind}_pos" in terms else None
            if kind in terms or pair:
                friction.setdefault(joint, {})[kind] = terms[kind] if kind in terms else float(np.mean(pair))
    data, reasons = identified_urdf(Path(res.config.urdf).read_text(encoding="utf-8"), res.model,
                                    res.consistent.inertial, parameter_vector(res.model), friction)
    return name, data, reasons


def joint_term_values(res: IdentifyResult) -> dict[str, dict[str, float]]:
    """{joint: {column kind: consistent value}}."""
    out: dict[str, dict[str, float]] = {j: {} for j in res.recorded}
    for value, name in zip(res.consistent.extra, res.consistent_extra_names()):
        joint, kind = name.rsplit(".", 1)
        out[joint][kind] = float(value)
    return out


def side_file(res: IdentifyResult, urdf_name: str) -> IdentifiedDynamics:
    """What URDF cannot hold (identified_model.py), for `robocal evaluate` and any reader."""
    cfg, proc = res.config, res.processed
    return IdentifiedDynamics(
        urdf_name, list(cfg.joints), effort_map_of(cfg, res.recorded), joint_term_values(res),
        {j: float(w) for j, w in zip(res.recorded, res.coulomb_width)},
        {j: float(d) for j, d in zip(res.recorded, res.delays)},
        {"cutoff_hz": float(proc.cutoff_hz), "order": int(proc.order), "velocity_source": proc.velocity_source,
         "edge_periods": float(cfg.signal.edge_periods)})


def result_dict(res: IdentifyResult, urdf: tuple | None = None) -> dict:
    """Everything the summary states, as JSON-ready values (units in the key names). urdf: `urdf_of(res)`
    when the caller has it already (it reads and edits the URDF file)."""
    proc, ols, fit = res.processed, res.ols, res.consistent
    bodies = res.model.names[1:]
    return {
        "config": res.config.source,
        "recorded_joints": res.recorded,
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
                  "coulomb_width": dict(zip(res.recorded, res.coulomb_width.tolist())),
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


def identified_urdf_entry(urdf: tuple) -> dict:
    name, data, reasons = urdf
    return {"file": name if data is not None else None, "not_written_because": [] if data is not None else reasons,
            "remarks": reasons if data is not None else []}


def torque_figure(res: IdentifyResult) -> bytes:
    """PNG: measured and predicted torques per recorded joint on the validation window."""
    from robocal.viz.plots import joint_torques   # optional dependency (matplotlib): only for a figure
    units = torque_units(res)
    buf = io.BytesIO()
    joint_torques(res.curves["t"], res.curves["measured"], {LABELS[m]: res.curves[m] for m in MODELS}, buf,
                  [j.replace("_joint", "") for j in res.recorded], units,
                  title="Held-out window: measured (low-pass filtered) vs predicted torque")
    return buf.getvalue()


def write_identification(res: IdentifyResult, out_dir: str | Path, force: bool = False) -> dict[str, Path]:
    urdf = urdf_of(res)
    d = result_dict(res, urdf)
    files = {"result.json": json.dumps(d, indent=1).encode(), "summary.txt": summary_text(res, d).encode()}
    name, data, _ = urdf
    if data is not None:
        files[name] = data
        files[SIDE_FILE] = yaml.safe_dump(side_file(res, name).to_dict(), sort_keys=False).encode()
    if res.curves:
        try:
            files["torque_validation.png"] = torque_figure(res)
        except ImportError:
            files["summary.txt"] += b"(matplotlib is not installed: no figure)\n"
    return write_folder(out_dir, files, force=force)


