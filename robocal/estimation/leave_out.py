"""Cross-validation without refits: the closed-form leave-out updates of one fit, as a CV table (docs/validation.md,
"Folds").

At the fit's solution (A^T r = 0, A the scaled Jacobian with any prior rows), leaving out the data rows G of a
fold and taking the Gauss-Newton step from the solution gives the held-out residual e_G = (I - H_GG)^-1 r_G
(H = A (A^T A)^-1 A^T) and the parameter change d_G = (A^T A - J_G^T J_G)^-1 J_G^T r_G, so the training rows'
residual after it is r_T + J_T d_G (robocal.estimation.model_criteria.approximate_loo). This is exact for a
problem linear in its parameters and the first-order version of refitting each fold for a calibration, at the
cost of one fit and one factorisation; each fold keeps the full fit's identifiability selection and prior.

`leave_out_table` gives the table `cross_validation.cv_table` gives (per fold: held-out samples, train and
held-out RMS of the error norm; pooled figures with the standard error across folds), or says why the
linearised fit does not allow it, and the caller refits: a robust loss (the linearisation ignores its weights),
a term spanning several samples, measurements other than lengths, angles and image points, a fold that is a
whole re-registered session (its frame is registered on it: a refit), a fit that did not converge or is
ill-conditioned, a Jacobian without full column rank, or a fold whose removal leaves a parameter without data.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import RobocalError
from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.cross_validation import CVTable, held_out_frames, pooled
from robocal.estimation.model_criteria import approximate_loo, linearise, norms
from robocal.estimation.problem import Problem
from robocal.residuals.base import Residual

KINDS = (("length", "mm"), ("angle", "mrad"), ("pixel", "px"))   # the units cv_table reports, in its order
STATUS = "closed form"                             # a fold's status: predicted from the fit, not refitted


class FitFailed(RobocalError):
    """The fit on all samples did not converge or is ill-conditioned: refitting its folds would take as long and
    describe a model that cannot be fitted. `result` holds the fit and its refusals."""

    def __init__(self, result):
        self.result = result
        super().__init__(f"the fit on all samples is {result.status}")


def closed_form_refusal(problem: Problem, folds: list[np.ndarray], options: CalibrationOptions | None = None) -> str:
    """Why the folds need refits before any fit ("" when the closed form applies so far)."""
    opt = options or CalibrationOptions()
    if opt.loss != "linear":
        return f"the {opt.loss} loss (the closed form reads the plain linearisation)"
    if any(type(r).term_samples is not Residual.term_samples for r in problem.residuals):
        return "a measurement term spans several samples"
    kinds = {u for r in problem.residuals for u in r.row_units} - {k for k, _ in KINDS}
    if kinds:
        return "measurements other than lengths, angles and image points (" + ", ".join(sorted(kinds)) + ")"
    if any(held_out_frames(problem, fold) for fold in folds):
        return "a held-out session's frame is registered on it"
    return ""


def leave_out_table(problem: Problem, folds: list[np.ndarray], options: CalibrationOptions | None = None,
                    refuse_failed: bool = False) -> tuple[CVTable | None, str]:
    """(the CV table of the closed-form leave-out of every fold, "") or (None, why refits are needed). Fits
    `problem` in place (when the closed form applies so far); a caller that refits after a refusal must start
    from the parameters as they were (see workflows.cv). refuse_failed: a fit on all samples that does not
    converge or is ill-conditioned raises FitFailed instead of asking for refits."""
    why = closed_form_refusal(problem, folds, options)
    if why:
        return None, why
    result = calibrate(problem, options)
    if result.status != "converged" and result.status != "implausible":
        if refuse_failed:
            raise FitFailed(result)
        return None, f"the fit on all samples is {result.status}"
    lin = linearise(problem)
    try:
        held = approximate_loo(lin, folds, steps=True)
    except ValueError as exc:         # rank deficient: not every free parameter is determined
        return None, str(exc)
    if held.undetermined:
        return None, f"fold {held.undetermined[0] + 1} leaves a parameter without data"
    return table_of(lin, folds, held), ""


def table_of(lin, folds: list[np.ndarray], held) -> CVTable:
    """The CV table (cv_table's figures) from the held-out residuals and the folds' parameter changes."""
    Jd, rd, scale = lin.J[lin.data], lin.r[lin.data], lin.scale[lin.data]
    samples = lin.sample[lin.data]
    kinds = [(k, u) for k, u in KINDS if np.any(lin.data & (lin.kind == k))]
    rows, held_sq, train_sq = [], {u: [] for _, u in kinds}, {u: [] for _, u in kinds}
    for fold, step in zip(folds, held.steps):
        out = np.isin(samples, fold)
        raw = np.where(out, held.raw, (rd + Jd @ step) / scale)   # held-out rows, training rows after the step
        figures = {}
        for kind, unit in kinds:
            of, v = norms(lin, raw, kind)
            ho = np.isin(of, fold)
            held_sq[unit].append(v[ho] ** 2)
            train_sq[unit].append(v[~ho] ** 2)
            figures[unit] = (v[ho], v[~ho])
        va, tr = figures[kinds[0][1]]
        rows.append({"held_out_samples": [int(i) for i in fold], "registered": [],
                     "train_rms_norm": float(np.sqrt(np.mean(tr ** 2))),
                     "validation_rms_norm": float(np.sqrt(np.mean(va ** 2))) if len(va) else None,
                     "status": STATUS})
    figures = {u: pooled(held_sq[u], train_sq[u]) for _, u in kinds}
    unit = kinds[0][1]
    rms, se, tr = figures.pop(unit)
    return CVTable(unit, rows, rms, se, tr, {u: {"rms": a, "stderr": b, "train": c} for u, (a, b, c) in figures.items()})
