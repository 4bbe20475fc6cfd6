"""Cross-validation over the samples of one problem, and where held-out postures lie against training.

`cross_validate(problem, folds)` fits the problem on all samples but one fold's and predicts that fold,
for every fold; `cv_table` does the same and reports train and held-out norm RMS per fold and overall
with a standard error. `kfold(n, k)` makes deterministic interleaved folds (k = n: leave-one-out);
`edge_folds(values)` holds out the postures at the ends of each joint's range, so each is predicted by a
fit that never reached that far. `posture_groups` sorts postures into repeated / new / out of range
against a training set. See docs/validation.md.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.problem import Problem
from robocal.estimation.prediction_errors import BlockErrors, PointStats, primary_errors, subset_residual, term_errors

def kfold(n_samples: int, k: int) -> list[np.ndarray]:
    """k interleaved folds of sample indices (fold i = i, i + k, ...): deterministic; k = n: leave-one-out."""
    if not 2 <= k <= n_samples:
        raise ValueError(f"need 2 <= k <= {n_samples} folds, got {k}")
    return [np.arange(i, n_samples, k) for i in range(k)]

def edge_folds(values: np.ndarray, fraction: float = 0.1) -> list[np.ndarray]:
    """Disjoint folds of the postures near the ends of each joint's range (values: (N, n_joints)).

    For each joint in turn, low end then high end: the postures whose reading lies within `fraction` of
    the joint's span from that end, less those already in a fold. Fitting without a fold shrinks that
    joint's range, so its postures are extrapolated; postures in no fold are never scored.
    Deterministic (no random draw), empty folds skipped."""
    values = np.atleast_2d(np.asarray(values, dtype=float))
    if not 0.0 < fraction < 0.5:
        raise ValueError(f"fraction must be in (0, 0.5), got {fraction}")
    taken = np.zeros(len(values), dtype=bool)
    folds = []
    for q in values.T:
        span = q.max() - q.min()
        if span <= 0.0:
            continue
        for zone in (q <= q.min() + fraction * span, q >= q.max() - fraction * span):
            fold = np.flatnonzero(zone & ~taken)
            if fold.size:
                folds.append(fold)
                taken[fold] = True
    return folds

@dataclass
class CrossValidation:
    """Held-out errors of every term (each predicted by the fit that did not see its sample)."""

    blocks: dict[str, BlockErrors]
    fold_values: list[dict[str, float]]      # fitted parameter values of each fold
    fold_ranks: list[int]                    # number of parameters each fold's fit determined

    def point_stats(self, block: str, point: int | str = 0, mask=None) -> PointStats:
        return self.blocks[block].point_stats(point, mask)

def cross_validate(problem: Problem, folds: list[np.ndarray], options: CalibrationOptions | None = None,
                   scored=None) -> CrossValidation:
    """Fit on all samples outside each fold, predict the fold's terms; `problem` itself is not changed.

    Every fit starts from the problem's current parameter values and makes its own identifiability
    choice. scored: names of the blocks to predict (default all).
    """
    initial = problem.params.copy()
    scored = [r.name for r in problem.residuals] if scored is None else list(scored)
    n = len(problem.values)
    parts: dict[str, list[BlockErrors]] = {name: [] for name in scored}
    values, ranks = [], []
    for fold in folds:
        train = np.setdiff1d(np.arange(n), fold)
        params = initial.copy()
        residuals = [subset_residual(r, train) for r in problem.residuals]
        sub = Problem(problem.robot, params, problem.joint_names, problem.values, residuals, problem.directions)
        result = calibrate(sub, options)
        values.append(params.values())
        ranks.append(result.selection.rank)
        held = [subset_residual(r, fold) for r in problem.residuals if r.name in scored]
        for name, be in term_errors(problem, params, held).items():
            parts[name].append(be)
    blocks = {}
    for name, bes in parts.items():
        samples = np.concatenate([b.samples for b in bes])
        order = np.argsort(samples, kind="stable")
        b0 = bes[0]
        blocks[name] = BlockErrors(name, b0.type_name, samples[order],
                                   np.concatenate([b.raw for b in bes])[order], b0.row_units, b0.labels)
    return CrossValidation(blocks, values, ranks)


@dataclass
class CVTable:
    unit: str
    folds: list[dict]             # per fold: n held out, train RMS, validation RMS
    rms: float                    # held-out norm RMS over every held-out point
    stderr: float                 # its standard error across folds (delta method on the per-fold mean squares)
    train_rms: float

    def to_dict(self) -> dict:
        return {"unit": self.unit, "validation_rms_norm": self.rms, "validation_rms_stderr": self.stderr,
                "train_rms_norm": self.train_rms, "folds": self.folds}

def cv_table(problem: Problem, folds: list[np.ndarray], options: CalibrationOptions | None = None) -> CVTable:
    """Fit on all samples outside each fold, score train and held-out norm errors; `problem` is unchanged."""
    opt = replace(options or CalibrationOptions(), register_before=False)
    initial = problem.params.copy()
    n = len(problem.values)
    rows, held_sq, train_sq, unit = [], [], [], ""
    for fold in folds:
        train = np.setdiff1d(np.arange(n), fold)
        params = initial.copy()
        sub = Problem(problem.robot, params, problem.joint_names, problem.values,
                      [subset_residual(r, train) for r in problem.residuals], problem.directions)
        result = calibrate(sub, opt)
        _, tr, unit = primary_errors(term_errors(sub))
        _, va, _ = primary_errors(term_errors(problem, params, [subset_residual(r, fold) for r in problem.residuals]))
        held_sq.append(va ** 2)
        train_sq.append(tr ** 2)
        rows.append({"held_out_samples": [int(i) for i in fold], "train_rms_norm": float(np.sqrt(np.mean(tr ** 2))),
                     "validation_rms_norm": float(np.sqrt(np.mean(va ** 2))) if len(va) else None,
                     "status": result.status})
    allsq = np.concatenate(held_sq)
    rms = float(np.sqrt(np.mean(allsq)))
    # per-fold mean squares weighted by size; standard error of their mean, then d sqrt(x) = dx / (2 sqrt(x))
    per = np.array([np.mean(h) for h in held_sq if len(h)])
    se_ms = float(np.std(per, ddof=1) / np.sqrt(len(per))) if len(per) > 1 else float("nan")
    return CVTable(unit, rows, rms, se_ms / (2 * rms) if rms > 0 else float("nan"),
                   float(np.sqrt(np.mean(np.concatenate(train_sq)))))


RANGE_MARGIN = 0.05     # rad or m: how far past a reference range a reading may lie and still count as inside

def range_excess(reference: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(N, n_joints) how far each reading of `values` lies beyond the range of `reference` (M, n_joints) on
    that joint, signed (negative: below the lowest reference reading), 0 inside the range; SI."""
    reference, values = np.atleast_2d(reference), np.atleast_2d(values)
    lo, hi = reference.min(0), reference.max(0)
    return np.where(values < lo, values - lo, np.where(values > hi, values - hi, 0.0))

def posture_groups(reference: np.ndarray, values: np.ndarray, tol: float = 0.01,
                   margin: float = RANGE_MARGIN) -> np.ndarray:
    """Group of each row of `values` (N, n_joints) against the postures of `reference` (M, n_joints), SI:
    0 repeated (every joint within `tol` of one reference posture), 1 new but inside the reference's
    joint ranges widened by `margin`, 2 out of range."""
    reference, values = np.atleast_2d(reference), np.atleast_2d(values)
    repeated = np.array([np.any(np.all(np.abs(reference - q) <= tol, axis=1)) for q in values], dtype=bool)
    inside = np.all(np.abs(range_excess(reference, values)) <= margin, axis=1)
    return np.where(repeated, 0, np.where(inside, 1, 2))
