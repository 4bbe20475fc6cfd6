"""Cross-validation over the samples of one problem, and where held-out postures lie against training.

`cross_validate(problem, folds)` fits the problem on all samples but one fold's and predicts that fold,
for every fold; `cv_table` does the same and reports train and held-out norm RMS per fold and overall
with a standard error. `kfold(n, k)` makes deterministic interleaved folds (k = n: leave-one-out);
`edge_folds(values)` holds out the postures at the ends of each joint's range, so each is predicted by a
fit that never reached that far. `posture_groups` sorts postures into repeated / new / out of range
against a training set. See docs/validation.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.problem import Problem
from robocal.errors import InputError
from robocal.estimation.prediction_errors import (UNITS, BlockErrors, PointStats, norm_errors, subset_residual,
                                                 term_errors)
from robocal.estimation.registration import fit_subset

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


def posture_folds(values: np.ndarray, k: int, tol: float = 0.01) -> list[np.ndarray]:
    """k folds of whole postures: samples whose every joint agrees within `tol` (rad or m) are one posture and
    stay in one fold (a repeat in training would predict its twin); postures are dealt to the folds in order
    of first appearance, interleaved. k >= number of postures: leave-one-posture-out. Deterministic."""
    values = np.atleast_2d(np.asarray(values, dtype=float))
    label = -np.ones(len(values), dtype=int)
    n_postures = 0
    for i in range(len(values)):
        if label[i] < 0:
            same = (label < 0) & np.all(np.abs(values - values[i]) <= tol, axis=1)
            label[same] = n_postures
            n_postures += 1
    k = min(k, n_postures)
    if k < 2:
        raise ValueError(f"need at least 2 distinct postures to hold one out, got {n_postures}")
    return [np.flatnonzero(label % k == f) for f in range(k)]


def session_folds(sessions) -> list[np.ndarray]:
    """Leave-one-session-out: one fold per session (robocal.estimation.sessions)."""
    return [sessions.samples_of(s) for s in range(len(sessions.names))]


def held_out_frames(problem: Problem, fold: np.ndarray) -> list[str]:
    """The frame parameters to register on a held-out fold before scoring it: a whole re-registered session's
    own frame (base.* and what the blocks place in the world, a camera's target, for the first session;
    base@<name>.* for the others), else none."""
    sessions = problem.sessions
    if sessions is None or not sessions.corrected:
        return []
    held = set(sessions.of_sample[fold].tolist())
    if len(held) != 1 or len(fold) != np.sum(sessions.of_sample == next(iter(held))):
        return []
    s = held.pop()
    names = sessions.parameter_names(s) if s else (
        [n for n in problem.params.names if n.startswith("base.")]
        + [n for r in problem.residuals for n in r.placed_per_session()])
    return [n for n in names if n in problem.params.names and problem.params[n].vary]


def hold_absent_sessions(params, sessions, train: np.ndarray) -> None:
    """Fix the frame corrections a training fold cannot see: those of sessions with no training sample, and,
    when the reference session has none, the first present session's (its frame becomes `base`, which the
    correction would otherwise duplicate)."""
    if sessions is None or not sessions.corrected:
        return
    present = sorted(set(sessions.of_sample[train].tolist()))
    held = [s for s in range(len(sessions.names)) if s not in present]
    if 0 in held and present:
        held.append(present[0])
    for s in held:
        for name in sessions.parameter_names(s):
            if name in params.names:
                params[name].vary = False


@dataclass
class CVTable:
    unit: str                     # the primary unit: mm when the blocks hold lengths, else mrad
    folds: list[dict]             # per fold: n held out, train RMS, validation RMS (primary unit)
    rms: float                    # held-out norm RMS over every held-out point (primary unit)
    stderr: float                 # its standard error across folds (delta method on the per-fold mean squares)
    train_rms: float
    others: dict = field(default_factory=dict)   # other units (mrad of pose blocks): {unit: {rms, stderr, train}}

    def to_dict(self) -> dict:
        return {"unit": self.unit, "validation_rms_norm": self.rms, "validation_rms_stderr": self.stderr,
                "train_rms_norm": self.train_rms, "folds": self.folds,
                "other_units": {u: {"validation_rms_norm": v["rms"], "validation_rms_stderr": v["stderr"],
                                    "train_rms_norm": v["train"]} for u, v in self.others.items()}}


def cv_table(problem: Problem, folds: list[np.ndarray], options: CalibrationOptions | None = None) -> CVTable:
    """Fit on all samples outside each fold, score train and held-out norm errors per unit (mm, mrad); a fold
    that is a whole re-registered session has its frame registered on its own data first (held_out_frames).
    `problem` is unchanged."""
    opt = replace(options or CalibrationOptions(), register_before=False)
    initial = problem.params.copy()
    n = len(problem.values)
    rows, held, trained = [], {}, {}
    for fold in folds:
        train = np.setdiff1d(np.arange(n), fold)
        params = initial.copy()
        hold_absent_sessions(params, problem.sessions, train)
        sub = Problem(problem.robot, params, problem.joint_names, problem.values,
                      [subset_residual(r, train) for r in problem.residuals], problem.directions, problem.sessions)
        result = calibrate(sub, opt)
        tr = norms_by_unit(term_errors(sub))          # before the held-out frames move the shared parameters
        tested = Problem(problem.robot, params, problem.joint_names, problem.values,
                         [subset_residual(r, fold) for r in problem.residuals], problem.directions, problem.sessions)
        frames = held_out_frames(problem, fold)
        if frames:
            fit_subset(tested, frames, opt)
        va = norms_by_unit(term_errors(tested))
        for unit in va:
            held.setdefault(unit, []).append(va[unit] ** 2)
            trained.setdefault(unit, []).append(tr.get(unit, np.zeros(0)) ** 2)
        unit = next(iter(va))
        rows.append({"held_out_samples": [int(i) for i in fold], "registered": frames,
                     "train_rms_norm": float(np.sqrt(np.mean(tr[unit] ** 2))),
                     "validation_rms_norm": float(np.sqrt(np.mean(va[unit] ** 2))) if len(va[unit]) else None,
                     "status": result.status})
    figures = {u: pooled(held[u], trained[u]) for u in held}
    unit = next(iter(figures))
    rms, se, tr = figures.pop(unit)
    return CVTable(unit, rows, rms, se, tr, {u: {"rms": a, "stderr": b, "train": c} for u, (a, b, c) in figures.items()})


def norms_by_unit(blocks: dict) -> dict[str, np.ndarray]:
    """{unit: every point's (mm), orientation's (mrad) or image point's (px) error norm over all blocks}, lengths
    first."""
    out: dict[str, list] = {}
    for kind, (_, unit, _) in UNITS.items():
        for b in blocks.values():
            e = norm_errors(b).get(kind)
            if e is not None:
                out.setdefault(unit, []).append(e.reshape(-1))
    if not out:
        raise InputError("no length, angle or pixel measurement to score")
    return {u: np.concatenate(v) for u, v in out.items()}


def pooled(held_sq: list[np.ndarray], train_sq: list[np.ndarray]) -> tuple[float, float, float]:
    """(held-out RMS over every held-out norm, its standard error across folds, train RMS)."""
    rms = float(np.sqrt(np.mean(np.concatenate(held_sq))))
    # per-fold mean squares; standard error of their mean, then d sqrt(x) = dx / (2 sqrt(x))
    per = np.array([np.mean(h) for h in held_sq if len(h)])
    se_ms = float(np.std(per, ddof=1) / np.sqrt(len(per))) if len(per) > 1 else float("nan")
    return rms, se_ms / (2 * rms) if rms > 0 else float("nan"), float(np.sqrt(np.mean(np.concatenate(train_sq))))


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
