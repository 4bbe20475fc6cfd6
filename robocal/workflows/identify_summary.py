"""The summary of `robocal identify`: what was done to the data, the model's terms, notes and findings
before any figure, the held-out figures, and what the constraints cost. See docs/dynamics_tiago.md."""
from __future__ import annotations

import numpy as np

from robocal.dynamics.constraint_cost import MEASURABLE_COST
from robocal.dynamics.identified_model import SIDE_FILE
from robocal.dynamics.identify_log import MODELS, IdentifyResult
from robocal.dynamics.inertial import parameter_vector
from robocal.workflows.identify_urdf import identified_urdf_entry, joint_unit, torque_units, urdf_of
from robocal.dynamics.chi_square import chi2_quantile

LABELS = {"cad": "CAD (URDF)", "ols": "OLS base parameters", "consistent": "physically consistent"}


def head_lines(res: IdentifyResult, d: dict) -> list[str]:
    """What comes before any figure: a solver stopped short, the input notes, the findings."""
    lines = [f"Dynamic identification: {res.config.source}", ""]
    if not res.consistent.converged:
        lines += [f"WARNING: the consistent fit's solver stopped short of its tolerance (Clarabel status "
                  f"{res.consistent.status}); its figures below are not an optimum.", ""]
    lines += [f"NOTE (input): {n}" for n in res.notes]
    return lines + ([f"FINDING: {f}" for f in d["findings"]]
                    or ["No finding: no plausibility bound or physical constraint is contradicted by the training "
                        "data beyond their noise."])


def brief_summary_text(res: IdentifyResult, d: dict) -> str:
    """`robocal identify -q`: the head (warnings, notes, findings), the consistent fit's status, the held-out
    figures, whether the model stays within the noise, and the URDF written; the rest is in summary.txt."""
    entry = d["identified_urdf"]
    lines = head_lines(res, d) + ["", f"Consistent fit: Clarabel status {res.consistent.status}; every body's "
                                      "pseudo-inertia PSD: " + str(all(v[1] for v in res.consistency.values()))]
    lines += validation_lines(res, torque_units(res))
    lines += ["", within_noise_verdict(res.within_noise),
              f"Identified URDF: {entry['file']}" if entry["file"] else
              "No identified URDF written: " + "; ".join(entry["not_written_because"]) + ".",
              "(every figure, the signal processing and the constraints' cost: summary.txt)"]
    return "\n".join(lines) + "\n"


def summary_text(res: IdentifyResult, d: dict | None = None) -> str:
    """The summary; d: identify_outputs.result_dict(res) when the caller has it already (its URDF entry and
    findings are reused). Warnings, input notes and findings come before any figure."""
    if d is None:
        d = {"findings": findings(res), "identified_urdf": identified_urdf_entry(urdf_of(res))}
    units = torque_units(res)
    lines = head_lines(res, d)
    lines += ["", "Signal processing:"]
    lines += [f"  - {c}" for c in res.processed.choices]
    vc = res.processed.velocity_check
    idx = [res.model.joints[res.model.getJointId(j)].idx_v for j in res.joint_terms]
    if vc:
        lines.append("  - logged vs differentiated velocities (recorded joints): RMS difference "
                     + ", ".join(f"{vc['rms_differentiated_minus_logged'][i]:.3g}" for i in idx)
                     + "; logged velocities lag by " + ", ".join(f"{vc['lag_of_logged_s'][i]:.3g}" for i in idx)
                     + " s")
    lines.append("")
    lines += transmission_lines(res)
    for p in res.parts:
        lines.append(f"{p.part.name}: training {[list(w) for w in p.part.train]} s ({int(p.train.sum())} samples), "
                     f"validation {[list(w) for w in p.part.validate] or 'none'} s ({int(p.check.sum())} samples, "
                     "held out).")
    lines += term_lines(res, units)
    lines += [f"OLS: {res.ols.selection.rank} base parameters, condition number {res.ols.condition:.4g}.",
              f"Consistent fit: CAD prior weight {res.consistent.prior_weight:.3g}, {prior_rule_text(res.prior)}; "
              f"Clarabel {res.consistent.iterations} iterations, status {res.consistent.status}."
              + grid_edge_note(res.prior),
              "Every body's pseudo-inertia PSD: " + str(all(v[1] for v in res.consistency.values())),
              *body_mass_lines(res)]
    lines += motor_term_lines(res)
    lines += validation_lines(res, units)
    wn = res.within_noise
    lines += [f"Training: the consistent fit's base parameters lie at squared distance "
              f"{wn['distance_in_noise_units']:.4g} from OLS in noise units (chi-square 95 % for "
              f"{wn['base_parameters']} base parameters: {wn['chi2_95']:.4g}; the filtered noise's correlation "
              f"across samples inflates variances by {wn['noise_inflation']:.3g}); per-joint RMS "
              "ratio to OLS " + ", ".join(f"{r:.3f}" for r in wn["rms_ratio"]) + ".",
              within_noise_verdict(wn)] + constraint_cost_lines(res.constraint_costs, {n: joint_unit(res.model, n) for n in
                                                                           list(res.joint_terms) + res.recorded},
                                                                 min(res.prior.grid))
    if res.wrench_rms:
        lines += ["", f"External force at {res.wrench_rms['frame']} during free motion (validation windows), RMS per "
                  "world axis x, y, z (force only):"]
        for m in MODELS:
            lines.append(f"  {LABELS[m]:24s}" + "  ".join(f"{f:8.3f} N" for f in res.wrench_rms[m]))
    entry = d["identified_urdf"]
    if entry["file"]:
        lines += ["", f"Identified URDF: {entry['file']} (the consistent inertias on each body's own link, viscous "
                      "and Coulomb friction as <dynamics damping friction>); every joint term, the delays and the "
                      f"signal processing in {SIDE_FILE}, which `robocal evaluate OUTPUT_DIR LOG.yaml` reads to "
                      "predict another log."] + [f"  ({r})" for r in entry["remarks"]]
    else:
        lines += ["", "No identified URDF written: " + "; ".join(entry["not_written_because"]) + "."]
    return "\n".join(lines) + "\n"


def validation_lines(res: IdentifyResult, units: list[str]) -> list[str]:
    if not res.validation:
        return ["", "No validation window: held-out figures come from `robocal evaluate OUTPUT_DIR LOG.yaml` on "
                    "another log (or list a validation window in the config)."]
    motors = res.channels is not None and res.channels.motors
    fmt = "10.4g" if motors else "10.3f"                # motor torques are small (N m on the motor shaft)
    lines = ["", f"Held-out torque RMSE per {'motor' if motors else 'joint'} against the low-pass filtered torque (% "
                 "of its torque range in the windows):", f"  {'model':24s}" + "".join(f"{j:>22s}" for j in res.recorded)]
    for m in MODELS:
        v = res.validation[m]
        lines.append(f"  {LABELS[m]:24s}" + "".join(f"{r:{fmt}} {u:3s} ({p:5.1f} %)"
                                                        for r, u, p in zip(v["rmse"], units, v["percent_of_range"])))
    ratio = np.array(res.validation["consistent"]["rmse"]) / np.array(res.validation["ols"]["rmse"])
    lines.append("  consistent / OLS: " + ", ".join(f"{r:.3f}" for r in ratio))
    lines.append("Against the logged torque itself (no filter: independent of the cut-off, the target to compare "
                 "other tools on):")
    for m in MODELS:
        lines.append((f"  {LABELS[m]:24s}" + "".join(f"{r:{fmt}} {u:3s}         "
                                                         for r, u in zip(res.validation[m]["rmse_against_logged"],
                                                                         units))).rstrip())
    logged_ratio = (np.array(res.validation["consistent"]["rmse_against_logged"])
                    / np.array(res.validation["ols"]["rmse_against_logged"]))
    lines += ["  consistent / OLS: " + ", ".join(f"{r:.3f}" for r in logged_ratio)]
    joints = res.validation["consistent"].get("rmse_joints")
    if joints:
        lines += ["The same errors mapped to the joints (tau = T^-T tau_m; joints whose torque needs only logged "
                  "motors), against the filtered torque:", f"  {'model':24s}" + "".join(f"{j:>22s}" for j in joints)]
        for m in MODELS:
            lines.append(f"  {LABELS[m]:24s}" + "".join(f"{r:10.4g} {joint_unit(res.model, j):3s}         "
                                                        for j, r in res.validation[m]["rmse_joints"].items()).rstrip())
    return lines


def transmission_lines(res: IdentifyResult) -> list[str]:
    """What the rows are when the logs are motor-side."""
    if res.channels is None or not res.channels.motors:
        return []
    tr = res.channels.transmission
    coupled = [j for j, row in zip(tr.joints, tr.matrix) if np.count_nonzero(row) > 1]
    return [f"Motor-side logs: {len(tr.motors)} motors to {len(tr.joints)} joints through q = T m + c (coupled joints: "
            f"{', '.join(coupled) or 'none'}; condition number of T {np.linalg.cond(tr.matrix):.3g}); the fit's rows "
            f"are the logged motors' torques ({', '.join(res.recorded)}), tau_m = T^T tau + each motor's own terms.",
            ""]


def motor_term_lines(res: IdentifyResult) -> list[str]:
    """Each logged motor's terms in the consistent fit, with their standard errors."""
    if res.channels is None or not res.channels.motors or not res.channels.motor_terms:
        return []
    names = res.consistent_extra_names()
    std = dict(zip(names, res.consistent_std[res.consistent.inertial.size:]))
    value = dict(zip(names, res.consistent.extra))
    units = {"coulomb": "N m", "viscous": "N m s/rad", "offset": "N m", "armature": "kg m^2"}
    lines = ["Motor terms (consistent fit, +- standard error; on the motor shaft; armature = rotor inertia; * not a "
             "base parameter on its own, the data see it only with a body's inertia: its value is the prior's split):"]
    for motor in res.recorded:
        lines.append(f"  {motor}: " + ", ".join(
            f"{k} {value[f'{motor}.{k}']:.4g} +- {std[f'{motor}.{k}']:.2g} {units[k]}"
            + ("" if f"{motor}.{k}" in res.ols.names else " *") for k in res.channels.motor_terms))
    return lines


def term_lines(res: IdentifyResult, units: list[str]) -> list[str]:
    """The terms in the model per joint and the candidates' tests (term_selection.py)."""
    with_terms = {j: t for j, t in res.joint_terms.items() if t}
    lines = ["Model terms per recorded joint: " + ("; ".join(f"{j} {', '.join(t)}" for j, t in with_terms.items())
                                                   or "none")]
    if res.term_tests:
        kept = [t for t in res.term_tests if t.kept]
        lines.append(f"Candidate terms tried on the training samples: {len(res.term_tests)}; kept (residual fall above "
                     "the Bonferroni chi-square threshold, noise units): "
                     + (", ".join(f"{t.joint}.{t.term} {t.statistic:.3g} > {t.threshold:.3g}"
                                  + (f" (delay {t.value:.3g} s)" if t.term == "delay" else "") for t in kept)
                        or "none") + " (every test in result.json)")
    return lines


def findings(res: IdentifyResult) -> list[str]:
    """The constraints the training data contradict beyond their noise (constraint_cost.py, at the weakest prior):
    a cost above the chi-square (1 degree of freedom) quantile at 1 - 0.05 / (number of binding constraints);
    and, without plausibility bounds, the bodies more than MASS_FACTOR from their CAD mass."""
    out = []
    if res.constraint_costs:
        threshold = chi2_quantile(1 - 0.05 / len(res.constraint_costs), 1)
        for c in res.constraint_costs:
            if c.cost > threshold:
                out.append(f"{c.constraint}: the data want otherwise (dropping it lowers the training objective by "
                           f"{c.cost:.3g} noise units > {threshold:.3g}; without it {c.value_without:.4g})")
    if not res.bounds:
        cad = parameter_vector(res.model)[0::10]
        for n, c, m, s in zip(res.model.names[1:], cad, res.consistent.inertial[0::10], res.mass_std()):
            if c > 0 and not 1 / MASS_FACTOR <= m / c <= MASS_FACTOR:
                out.append(f"body of {n}: mass {m:.3g} +- {s:.2g} kg, more than {MASS_FACTOR:g}x from CAD {c:.3g} kg")
    return out


def prior_rule_text(prior) -> str:
    """How the prior weight was chosen (prior_weight.py), in words."""
    if prior.rule == "holdout":
        return (f"chosen on the training window (fit on its first {100 * prior.split_fraction:.0f} % less the "
                f"filter's reach, {prior.gap_s:.3g} s, scored on the rest)")
    if prior.rule == "within_bounds_noise":
        return (f"by the within-bounds-noise rule (the strongest weight of model.prior_grid whose fit stays within "
                f"the noise of the weakest weight's fit under the same constraints: squared distance at most "
                f"{prior.bound:.4g}, the chi-square 95 % quantile)")
    return (f"by the within-noise rule (the strongest weight of model.prior_grid whose fit stays within the "
            f"unconstrained fit's noise on the training window: squared distance at most {prior.bound:.4g}, the "
            "chi-square 95 % quantile)")


def grid_edge_note(prior) -> str:
    """Said when the chosen prior weight is the grid's smallest or largest: the best may lie beyond it. Under
    the within-noise rule the smallest means no weight met the bound."""
    if prior.rule.startswith("within") and not prior.attained:
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
            "physical consistency and plausibility cost fit on this data (the findings say where); compare held-out "
            "figures (a validation window, or robocal evaluate on another log) before using it.")


def constraint_cost_lines(costs, joint_units: dict[str, str], weakest: float, shown: int = 5) -> list[str]:
    """The constraints that cost the fit most on the training samples at the weakest prior (constraint_cost.py);
    joint_units: {recorded joint: 'N' or 'N m'}."""
    if not costs:
        return [f"No constraint binds at the weakest prior ({weakest:.3g}): the data sit inside them."]
    costly = [c for c in costs if c.cost >= MEASURABLE_COST][:shown]
    lines = [f"Binding constraints at the weakest prior ({weakest:.3g}): {len(costs)} (the fit without one breaks "
             f"it). Those costing the fit at least {MEASURABLE_COST:g} noise unit (the fall of its training objective, "
             "same units, when dropped alone; the value it then takes):"]
    for c in costly:
        if c.kind == "body":
            what, unit = "smallest pseudo-inertia eigenvalue", "kg m^2"
        elif c.kind.startswith("mass"):
            what, unit = "mass", "kg"
        elif c.kind == "ellipsoid":
            what, unit = "tr(Q J)", "kg"
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
    std = res.mass_std()
    lines = ["Body masses, CAD -> consistent +- standard error (kg): " + ", ".join(
        f"{n} {c:.3g} -> {m:.3g} +- {s:.2g}" for n, c, m, s in zip(names, cad, fit, std))]
    if res.bounds:
        lines.append(f"Plausibility bounds: mass in [{res.config.mass_ratio[0]:g}, {res.config.mass_ratio[1]:g}] x CAD, "
                     "mass inside each body's bounding ellipsoid (" + ", ".join(
                         f"{b.joint}: {b.source}" for b in res.bounds) + "; result.json)")
    far = [n for n, c, m in zip(names, cad, fit) if c > 0 and not 1 / MASS_FACTOR <= m / c <= MASS_FACTOR]
    if far:
        lines.append(f"NOTE: {', '.join(far)}: more than {MASS_FACTOR:g}x from the CAD mass. The data explain the "
                     "torques with another mass distribution; check the torque convention (offsets, gear ratios, "
                     "motor constants) before using these masses.")
    return lines
