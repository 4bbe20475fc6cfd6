"""The words of a CalibrationResult: its summary (terminal and summary.txt) and its identifiability story.

One story everywhere: the counts are those of robocal.estimation.determinacy's classes (every requested
parameter in exactly one), the same in the summary, result.json ("identifiability") and report.html. With
`limit` (the terminal), a long list of names shows its first `limit` and a count; summary.txt lists all.
"""
from __future__ import annotations

import numpy as np

from robocal.estimation.session_figures import session_lines

from robocal.estimation.determinacy import DETERMINED, FIXED, LOOSE, PRIOR_ONLY, WEAK
from robocal.estimation.physical_scale import FINDING_SCALES, FINDING_SIGMAS

MAX_DIRECTIONS = 6      # weak directions in words (all of them in result.json)
FINDING_RULE = (f"|value - nominal| > {FINDING_SCALES:g} physical scales and data-only standard error < "
                f"|value - nominal| / {FINDING_SIGMAS:g}")


def names_text(names: list[str], limit: int | None) -> str:
    if limit is None or len(names) <= limit:
        return ", ".join(names)
    return ", ".join(names[:limit]) + f" and {len(names) - limit} more (all in summary.txt and result.json)"


def threshold_text(thresholds: tuple[float, float]) -> str:
    return f"{thresholds[0] * 1e3:.3g} mm / {thresholds[1] * 1e3:.3g} mrad"


def class_counts_sentence(det, requested: int, thresholds: tuple[float, float]) -> str:
    c = det.counts()
    return (f"Of {requested} requested parameters, {det.identifiable} are identifiable from the data alone: "
            f"{c[DETERMINED]} {DETERMINED} (data-only standard error within {threshold_text(thresholds)}), "
            f"{c[WEAK]} {WEAK} (within their physical scale), {c[LOOSE]} {LOOSE} (beyond it); "
            f"{c[PRIOR_ONLY]} {PRIOR_ONLY} (the data cannot separate them); {c[FIXED]} {FIXED} at their initial "
            f"value (the data cannot separate them and they have no prior).")


def identifiability_statements(result, limit: int | None = None) -> list[str]:
    det = result.determinacy
    if det is None:            # a result built without the determinacy step: the selection alone
        return [f"{result.selection.rank} of {len(result.requested)} requested parameters are kept by the "
                f"selection."] + [s + "; fixed at its initial value." for s in result.selection.describe()]
    lines = [class_counts_sentence(det, len(result.requested), result.determined_thresholds)]
    lines += [s + "; fixed at its initial value." for s in result.selection.describe()]
    for cls, words in ((PRIOR_ONLY, "Set by the prior only, not by the data"),
                       (LOOSE, "Loose: the data see them less well than their physical scale")):
        names = det.names_in(cls)
        if names:
            lines.append(f"{words} ({len(names)}): {names_text(names, limit)}.")
    if result.default_prior is not None:
        lines.append(result.default_prior.describe())
    if any(result.params[n].prior_sigma is not None for n in result.params.free_names):
        lines.append("Standard errors: '+-' is the fit's, with the prior's contribution; 'data alone' is what the "
                     "data give with the parameters set by the prior held at their values (n/a: the data cannot "
                     "tell it).")
    shown = det.directions[:MAX_DIRECTIONS]
    lines += ["Weak direction: " + d.describe() + "." for d in shown]
    if len(shown) < len(det.directions):
        lines.append(f"And {len(det.directions) - len(shown)} less weak directions (every one in result.json: "
                     "identifiability.weak_directions).")
    if result.ill_conditioned:
        lines.append(f"The fit is ill-conditioned: condition number {result.condition:.3g} exceeds "
                     f"{result.condition_limit:.3g}; estimates along the weakest directions are unreliable.")
    return lines


def identifiability_dict(result) -> dict:
    """result.json's "identifiability": the class counts and members, and what the standard errors mean."""
    det = result.determinacy
    out = {"requested": len(result.requested), "rank_rtol": result.selection.rtol,
           "statements": identifiability_statements(result)}
    if det is None:
        return out
    out.update({"identifiable_from_data": det.identifiable, **det.to_dict(),
                "set_by_prior": det.names_in(PRIOR_ONLY), "fixed_at_initial": det.names_in(FIXED),
                "loose": det.names_in(LOOSE),
                "thresholds": {"length_m": result.determined_thresholds[0],
                               "angle_rad": result.determined_thresholds[1]},
                "standard_errors": "parameters[].stderr: the fit's, with the prior's contribution; "
                                   "parameters[].stderr_data_only: the data's alone, the parameters set by the prior "
                                   "held at their values (null: the data cannot tell it)"})
    return out


def finding_lines(result, limit: int | None = None) -> list[str]:
    if not result.findings:
        return []
    shown = result.findings if limit is None else result.findings[:limit]
    lines = [f"Findings: {len(result.findings)} parameter(s) the data determine firmly, far from nominal "
             f"({FINDING_RULE}); written to the calibrated model. Check them on the robot:"]
    lines += [f"  - {f.describe()}." for f in shown]
    if len(shown) < len(result.findings):
        lines.append(f"  and {len(result.findings) - len(shown)} more (all in summary.txt and result.json).")
    return lines


def parameter_lines(result) -> list[str]:
    det = result.determinacy
    lines = ["Estimated parameters (SI units; +- the fit's standard error; data alone: without the prior's "
             "contribution):",
             f"  {'':<32}{'value':>14} {'unit':<10}{'+- s.e.':>12}{'data alone':>12}   class"]
    for name in result.params.free_names:
        p = result.params[name]
        se = f"{p.stderr:.3g}" if p.stderr is not None and np.isfinite(p.stderr) else "n/a"
        sd = f"{p.stderr_data:.3g}" if p.stderr_data is not None and np.isfinite(p.stderr_data) else "n/a"
        cls = det.classes.get(name, "") if det is not None else ""
        lines.append(f"  {name:<32}{p.value:>+14.6g} {p.unit:<10}{se:>12}{sd:>12}   {cls}")
    return lines


def summary_text(result, limit: int | None = None) -> str:
    lines = []
    for k, r in enumerate(result.refusals, 1):
        lines += r.lines(k, limit)
    lines += [""] if result.refusals else []
    lines += finding_lines(result, limit) + ([""] if result.findings else [])
    lines += [f"Calibration {result.status}: {result.solve.message} after {result.solve.nit} iterations",
              f"{result.n_rows} residual rows, {len(result.params.free_names)} estimated parameters, "
              f"condition number {result.condition:.3g}, residual/sigma {np.sqrt(result.sigma2):.3f}", "",
              "Errors: RMS of the error norm (3D per point / orientation; |e| per row otherwise), max in "
              "brackets. Before = the nominal robot with only the registration frames fitted"
              + (f" ({', '.join(sorted({n.split('.')[0] for n in result.registration}))})" if result.registration
                 else " (none float: the model as given)") + ".",
              f"{'block':<20}{'type':<14}{'rows':>6}   {'RMS before: |e| (max)':>30}   "
              f"{'RMS after: |e| (max)':>30}   {'after, per component':>22}"]
    for b0, b1 in zip(result.before, result.after):
        fmt = ", ".join(f"{v:.4g} {k}" for k, v in b1.rms.items())
        lines.append(f"{b0.name:<20}{b0.type_name:<14}{b0.rows:>6}   {b0.headline():>30}   "
                     f"{b1.headline():>30}   {fmt:>22}")
    lines += session_lines(result.sessions)
    lines += [""] + parameter_lines(result)
    lines += ["", "Identifiability:"] + [f"  {s}" for s in identifiability_statements(result, limit)]
    return "\n".join(lines)

