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

from robocal.dynamics.constraint_cost import MEASURABLE_COST
from robocal.dynamics.identify_log import MODELS
from robocal.workflows.identify import IdentifyResult
from robocal.dynamics.inertial import parameter_vector
from robocal.dynamics.urdf_inertials import identified_urdf
from robocal.io.output_folder import write_folder

LABELS = {"cad": "CAD (URDF)", "ols": "OLS base parameters", "consistent": "physically consistent"}


def torque_units(res: IdentifyResult) -> list[str]:
    """N for a prismatic recorded joint, N m for a revolute one."""
    return ["N" if res.model.joints[res.model.getJointId(j)].shortname().startswith("JointModelP") else "N m"
            for j in res.recorded]


def urdf_of(res: IdentifyResult) -> tuple[str, bytes | None, list[str]]:
    """(file name, URDF bytes or None, why not): the input URDF carrying the consistent model's inertias
    (urdf_inertials.py); none when the solver stopped short or an edited link would not be realisable."""
    name = f"{Path(res.config.urdf).stem}_identified.urdf"
    if not res.consistent.converged:
        return name, None, [f"the consistent fit's solver stopped short (status {res.consistent.status})"]
    friction: dict[str, dict[str, float]] = {}
    for value, term in zip(res.consistent.extra, res.consistent_extra_names()):
        joint, kind = term.rsplit(".", 1)
        if kind in ("viscous", "coulomb"):         # the terms URDF's <dynamics damping friction> holds
            friction.setdefault(joint, {})[kind] = float(value)
    data, reasons = identified_urdf(Path(res.config.urdf).read_text(encoding="utf-8"), res.model,
                                    res.consistent.inertial, parameter_vector(res.model), friction)
    return name, data, reasons


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
        "windows_s": {"train": list(res.config.train), "validate": list(res.config.validate),
                      "train_samples": int(res.train.sum()), "validate_samples": int(res.check.sum())},
        "ols": {"names": ols.names, "values": ols.values.tolist(), "std": ols.std.tolist(),
                "condition_number": ols.condition, "rank": ols.selection.rank,
                "residual_rms_per_joint": ols.sigma.tolist(), "dropped": ols.selection.describe()},
        "consistent": {"prior_weight": fit.prior_weight, "prior_rule": res.prior.rule, "prior_grid": res.prior.grid,
                       "prior_scores": res.prior.scores, "prior_bound": res.prior.bound,
                       "prior_split": res.prior.split_fraction,
                       "solver_iterations": fit.iterations, "solver_status": fit.status, "converged": fit.converged,
                       "inertial": {b: p.tolist() for b, p in zip(bodies, fit.inertial.reshape(-1, 10))},
                       "extra": dict(zip(res.consistent_extra_names(), fit.extra.tolist())),
                       "pseudo_inertia_min_eigenvalue": {b: v[0] for b, v in res.consistency.items()},
                       "physically_consistent": {b: v[1] for b, v in res.consistency.items()}},
        "validation_rmse": res.validation,
        "validation_torque_range": res.torque_range,
        "training_rms": res.training_rms,
        "consistent_vs_ols": res.within_noise,
        "constraint_costs_noise_units": [{"constraint": c.constraint, "cost": c.cost, "value_without": c.value_without}
                                         for c in res.constraint_costs],
        "external_force_rms_N": res.wrench_rms,
        "identified_urdf": identified_urdf_entry(urdf if urdf is not None else urdf_of(res)),
    }


def identified_urdf_entry(urdf: tuple) -> dict:
    name, data, reasons = urdf
    return {"file": name if data is not None else None, "not_written_because": reasons}


def summary_text(res: IdentifyResult, d: dict | None = None) -> str:
    """The summary; d: `result_dict(res)` when the caller has it already."""
    d = d if d is not None else result_dict(res)
    units = d["torque_units"]
    lines = [f"Dynamic identification: {res.config.source}", ""]
    if not res.consistent.converged:        # said before any figure
        lines += [f"WARNING: the consistent fit's solver stopped short of its tolerance (Clarabel status "
                  f"{res.consistent.status}); its figures below are not an optimum.", ""]
    lines.append("Signal processing:")
    lines += [f"  - {c}" for c in res.processed.choices]
    vc = res.processed.velocity_check
    idx = [res.model.joints[res.model.getJointId(j)].idx_v for j in res.recorded]
    lines.append("  - logged vs differentiated velocities (recorded joints): RMS difference "
                 + ", ".join(f"{vc['rms_differentiated_minus_logged'][i]:.3g}" for i in idx)
                 + "; logged velocities lag by " + ", ".join(f"{vc['lag_of_logged_s'][i]:.3g}" for i in idx) + " s")
    w = d["windows_s"]
    lines += ["", f"Training window {w['train']} s ({w['train_samples']} samples), validation {w['validate']} s "
              f"({w['validate_samples']} samples, held out).",
              f"OLS: {d['ols']['rank']} base parameters, condition number {d['ols']['condition_number']:.4g}.",
              f"Consistent fit: CAD prior weight {res.consistent.prior_weight:.3g}, {prior_rule_text(res.prior)}; "
              f"Clarabel {res.consistent.iterations} iterations, status {res.consistent.status}."
              + grid_edge_note(res.prior),
              "Every body's pseudo-inertia PSD: " + str(all(v[1] for v in res.consistency.values())),
              *body_mass_lines(res),
              "", "Held-out torque RMSE per joint against the low-pass filtered torque (% of the joint's torque "
                  "range in the window):"]
    header = f"  {'model':24s}" + "".join(f"{j:>22s}" for j in res.recorded)
    lines.append(header)
    for m in MODELS:
        v = res.validation[m]
        lines.append(f"  {LABELS[m]:24s}" + "".join(f"{r:10.3f} {u:3s} ({p:5.1f} %)"
                                                        for r, u, p in zip(v["rmse"], units, v["percent_of_range"])))
    ratio = np.array(res.validation["consistent"]["rmse"]) / np.array(res.validation["ols"]["rmse"])
    lines.append("  consistent / OLS: " + ", ".join(f"{r:.3f}" for r in ratio))
    lines.append("Against the logged torque itself (no filter: independent of the cut-off, the target to compare "
                 "other tools on):")
    for m in MODELS:
        lines.append((f"  {LABELS[m]:24s}" + "".join(f"{r:10.3f} {u:3s}         "
                                                         for r, u in zip(res.validation[m]["rmse_against_logged"],
                                                                         units))).rstrip())
    logged_ratio = (np.array(res.validation["consistent"]["rmse_against_logged"])
                    / np.array(res.validation["ols"]["rmse_against_logged"]))
    wn = res.within_noise
    lines += ["  consistent / OLS: " + ", ".join(f"{r:.3f}" for r in logged_ratio),
              f"Training: the consistent fit's base parameters lie at squared distance "
              f"{wn['distance_in_noise_units']:.4g} from OLS in noise units (chi-square 95 % for "
              f"{wn['base_parameters']} base parameters: {wn['chi2_95']:.4g}; the filtered noise's correlation "
              f"across samples inflates variances by {wn['noise_inflation']:.3g}); per-joint RMS "
              "ratio to OLS " + ", ".join(f"{r:.3f}" for r in wn["rms_ratio"]) + ".",
              within_noise_verdict(wn)] + constraint_cost_lines(res.constraint_costs,
                                                           dict(zip(res.recorded, units))) + [
              "", f"External force at {res.wrench_rms['frame']} during free motion (validation window), RMS per "
              "world axis x, y, z (force only):"]
    for m in MODELS:
        lines.append(f"  {LABELS[m]:24s}" + "  ".join(f"{f:8.3f} N" for f in res.wrench_rms[m]))
    entry = d["identified_urdf"]
    if entry["file"]:
        lines += ["", f"Identified URDF: {entry['file']} (the consistent inertias on each body's own link, viscous "
                      "and Coulomb friction as <dynamics damping friction>; rotor inertias and offsets are in "
                      "result.json)."]
    else:
        lines += ["", "No identified URDF written: " + "; ".join(entry["not_written_because"]) + "."]
    return "\n".join(lines) + "\n"


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
    try:
        files["torque_validation.png"] = torque_figure(res)
    except ImportError:
        files["summary.txt"] += b"(matplotlib is not installed: no figure)\n"
    return write_folder(out_dir, files, force=force)


def prior_rule_text(prior) -> str:
    """How the prior weight was chosen (prior_weight.py), in words."""
    if prior.rule == "holdout":
        return (f"chosen on the training window (fit on its first {100 * prior.split_fraction:.0f} % less the "
                f"filter's reach, {prior.gap_s:.3g} s, scored on the rest)")
    return (f"by the within-noise rule (the strongest weight of model.prior_grid whose fit stays within the "
            f"unconstrained fit's noise on the training window: squared distance at most {prior.bound:.4g}, the "
            "chi-square 95 % quantile)")


def grid_edge_note(prior) -> str:
    """Said when the chosen prior weight is the grid's smallest or largest: the best may lie beyond it. Under
    the within-noise rule the smallest means no weight met the bound."""
    if prior.rule == "within_noise" and not prior.attained:
        return (f" NOTE: no weight of the grid meets that bound (the weakest, {prior.chosen:.3g}, lies at "
                f"{prior.scores[0]:.4g} > {prior.bound:.4g}): the physical constraints themselves cost more than the "
                "noise, so the weakest prior is used.")
    if len(prior.grid) < 2 or prior.chosen not in (min(prior.grid), max(prior.grid)):
        return ""
    side = "largest" if prior.chosen == max(prior.grid) else "smallest"
    return (f" NOTE: {prior.chosen:.3g} is the {side} weight of model.prior_grid; the data may favour one beyond "
            f"it (widen the grid).")


def within_noise_verdict(wn: dict) -> str:
    """One sentence: is the consistent model within the unconstrained fit's noise on the training window?"""
    if wn["distance_in_noise_units"] <= wn["chi2_95"]:
        return "The consistent model lies within the unconstrained fit's noise (below the 95 % quantile)."
    return ("NOTE: the consistent model lies beyond the unconstrained fit's noise (above the 95 % quantile): "
            "physical consistency costs fit on this data; compare the held-out figures above before using it.")


def constraint_cost_lines(costs, joint_units: dict[str, str], shown: int = 5) -> list[str]:
    """The constraints that cost the consistent fit most on the training window (constraint_cost.py);
    joint_units: {recorded joint: 'N' or 'N m'}."""
    if not costs:
        return ["No physical constraint binds: the consistent fit is the unconstrained one with the prior."]
    costly = [c for c in costs if c.cost >= MEASURABLE_COST][:shown]
    lines = [f"Binding physical constraints: {len(costs)} (the fit without one breaks it). Those costing the fit "
             f"at least {MEASURABLE_COST:g} noise unit (the fall of its training objective, same units, when "
             "dropped alone; the value it then takes):"]
    for c in costly:
        if c.kind == "body":
            what, unit = "smallest pseudo-inertia eigenvalue", "kg m^2"
        else:
            what, unit = "value", term_unit(c.kind, joint_units.get(c.joint, "N m"))
        lines.append(f"  {c.constraint:40s} {c.cost:9.3g}   ({what} without it {c.value_without:.3g} {unit})")
    if len(costs) > len(costly):
        lines.append(f"  ({len(costs) - len(costly)} more in result.json)")
    return lines


def term_unit(term: str, torque_unit: str) -> str:
    """Unit of an extra term of a joint whose torque is in torque_unit ('N' prismatic, 'N m' revolute)."""
    revolute = torque_unit == "N m"
    units = {"armature": "kg m^2" if revolute else "kg", "viscous": torque_unit + (" s/rad" if revolute else " s/m")}
    return units.get(term, torque_unit)


#: a consistent body's mass outside [1/MASS_FACTOR, MASS_FACTOR] x its CAD mass is pointed out
MASS_FACTOR = 2.0


def body_mass_lines(res: IdentifyResult) -> list[str]:
    """Each body's mass, CAD and consistent: realisable is not the same as plausible. A NOTE names the bodies
    far from their CAD mass (the data explain the torques with another mass distribution: check the torque
    convention, offsets and gear ratios before trusting the masses)."""
    cad = parameter_vector(res.model)[0::10]
    fit = res.consistent.inertial[0::10]
    names = res.model.names[1:]
    lines = ["Body masses, CAD -> consistent (kg): " + ", ".join(f"{n} {c:.3g} -> {m:.3g}"
                                                                for n, c, m in zip(names, cad, fit))]
    far = [n for n, c, m in zip(names, cad, fit) if c > 0 and not 1 / MASS_FACTOR <= m / c <= MASS_FACTOR]
    if far:
        lines.append(f"NOTE: {', '.join(far)}: more than {MASS_FACTOR:g}x from the CAD mass. The data explain the "
                     "torques with another mass distribution; check the torque convention (offsets, gear ratios, "
                     "motor constants) before using these masses.")
    return lines
