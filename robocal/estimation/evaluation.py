"""Scoring a fitted model on other data, and cross-validation over the samples of one problem.

`term_errors(problem, params)` evaluates every residual term of `problem` with the parameter values of
`params` (a fitted ParameterSet, typically from another problem with the same residual names), without
a fit: prediction - measurement, SI units, every row (also rows of weight 0). Point-like blocks (all rows
lengths, three per point: point, rigid_points) are scored per point: RMSE per axis, RMSE of the norm, and
the largest norm, in mm (`BlockErrors.point_stats`).

`cross_validate(problem, folds)` fits the problem on all samples but one fold's and predicts that fold,
for every fold; the held-out errors of all folds together score a modelling choice on one data set.
`kfold(n, k)` makes deterministic interleaved folds (k = n: leave-one-out); `edge_folds(values)` holds
out the postures at the ends of each joint's range, so each is predicted by a fit that never reached that
far: a training-only estimate of the error outside the calibrated range.

`setup_for_data(config, csv)` builds a config's problem on another CSV file of the same layout (a
validation session); `posture_groups` sorts postures into repeated / new / out of range against a
training set. The library never prints.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.io.config import Setup, read_yaml, setup_from_config
from robocal.io.tables import read_csv
from robocal.errors import InputError
from robocal.model.kinematics import ModelState
from robocal.model.parameters import ParameterSet
from robocal.residuals.base import Residual
from robocal.estimation.problem import Problem

MM = 1e3


@dataclass
class PointStats:
    """Position errors of one point over a set of samples, in mm."""

    n: int
    rmse_axes: np.ndarray      # (3,) RMSE along x, y, z of the measurement frame
    rmse_norm: float           # sqrt(mean |e|^2)
    max_norm: float            # max |e|

    def to_dict(self) -> dict:
        return {"n": self.n, "rmse_x_mm": float(self.rmse_axes[0]), "rmse_y_mm": float(self.rmse_axes[1]),
                "rmse_z_mm": float(self.rmse_axes[2]), "rmse_norm_mm": self.rmse_norm, "max_norm_mm": self.max_norm}


def point_stats(errors: np.ndarray) -> PointStats:
    """Statistics of (n, 3) position errors in metres."""
    e = np.asarray(errors, dtype=float).reshape(-1, 3) * MM
    if not len(e):
        return PointStats(0, np.full(3, np.nan), float("nan"), float("nan"))
    norm = np.linalg.norm(e, axis=1)
    return PointStats(len(e), np.sqrt(np.mean(e ** 2, axis=0)), float(np.sqrt(np.mean(norm ** 2))),
                      float(np.max(norm)))


@dataclass
class BlockErrors:
    """Errors of one residual block: raw (n_terms, dim) in SI units, the sample of each term."""

    name: str
    type_name: str
    samples: np.ndarray
    raw: np.ndarray
    row_units: tuple[str, ...]
    labels: list[str] = field(default_factory=list)   # point labels of a point-like block

    @property
    def is_points(self) -> bool:
        return self.raw.shape[1] % 3 == 0 and all(u == "length" for u in self.row_units)

    def points(self) -> np.ndarray:
        """(n_terms, n_points, 3) position errors (m) of a point-like block."""
        if not self.is_points:
            raise ValueError(f"block '{self.name}' ({self.type_name}) does not hold point positions")
        return self.raw.reshape(len(self.raw), -1, 3)

    def point_stats(self, point: int | str = 0, mask: np.ndarray | None = None) -> PointStats:
        """Statistics of one point (index or label), over the terms selected by `mask` (all if None)."""
        j = self.labels.index(point) if isinstance(point, str) else int(point)
        e = self.points()[:, j]
        return point_stats(e if mask is None else e[np.asarray(mask)])

    def subset(self, keep: np.ndarray) -> "BlockErrors":
        keep = np.asarray(keep)
        return BlockErrors(self.name, self.type_name, self.samples[keep], self.raw[keep], self.row_units, self.labels)


def _labels(res) -> list[str]:
    if getattr(res, "labels", None):
        return list(res.labels)
    return [res.name] if res.dim == 3 else [f"p{i + 1}" for i in range(res.dim // 3)]


def term_errors(problem: Problem, params: ParameterSet | None = None, residuals=None) -> dict[str, BlockErrors]:
    """Prediction - measurement of every term of `problem`'s residuals at `params` (default: its own).

    `params` must name every auxiliary parameter of the residuals (same residual names); parameters it
    lacks on the robot side keep their nominal (zero) effect.
    """
    params = problem.params if params is None else params
    residuals = problem.residuals if residuals is None else residuals
    ms = ModelState(problem.robot, params, problem.joint_names)
    states = problem.states(ms)
    out = {}
    for res in residuals:
        names = [p.name for p in res.aux_parameters()]
        missing = [n for n in names if n not in params]
        if missing:
            raise InputError(f"the parameters lack the set-up quantities of block '{res.name}': "
                             f"{', '.join(missing)}")
        aux = np.array([params[n].value for n in names])
        raw = np.array([res.evaluate(k, states, aux).r for k in range(res.n_terms)]).reshape(res.n_terms, res.dim)
        out[res.name] = BlockErrors(res.name, res.type_name, np.asarray(res.samples).copy(), raw,
                                    tuple(res.row_units), _labels(res))
    return out


def subset_residual(res, keep_samples):
    """A copy of a residual with only the terms whose samples are all in `keep_samples`."""
    if type(res).term_samples is Residual.term_samples:       # one sample per term: vectorised (a million terms)
        keep = np.isin(np.asarray(res.samples), np.asarray(keep_samples, dtype=int))
    else:
        keep_samples = set(int(s) for s in keep_samples)
        keep = np.array([all(s in keep_samples for s in res.term_samples(k)) for k in range(res.n_terms)],
                        dtype=bool)
    new = copy.copy(res)
    for attr, value in vars(res).items():
        if isinstance(value, np.ndarray) and attr not in ("sigma", "weights") and value.ndim >= 1 \
                and len(value) == res.n_terms:
            setattr(new, attr, value[keep])
    return new


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


def setup_for_data(config: str | Path, csv: str | Path | None = None, parameters: dict | None = None) -> Setup:
    """A config's problem, optionally on another CSV file of the same columns and with changed parameters.

    csv replaces `data.csv` and every block's `csv` (absolute, or relative to the config's folder);
    parameters: keys merged into the config's `parameters` section (e.g. {"priors": {...}}).
    """
    path = Path(config).resolve()
    raw = read_yaml(path)
    if parameters and isinstance(raw, dict):
        raw = {**raw, "parameters": {**(raw.get("parameters") or {}), **parameters}}
    table = None if csv is None else read_csv((path.parent / csv).resolve())
    return setup_from_config(raw, path.parent, str(path), table=table)


def portable_config(config: str | Path, parameters: dict | None = None) -> bytes:
    """The config's YAML with its file paths made absolute (robot.urdf, package_dirs, every csv) and
    `parameters` merged in: stored in an output folder, it rebuilds the same model from there
    (`robocal evaluate`)."""
    path = Path(config).resolve()
    raw = read_yaml(path)            # a fresh parse: edited below, never shared
    here = path.parent
    robot = raw.get("robot") or {}
    if "urdf" in robot:
        robot["urdf"] = str((here / robot["urdf"]).resolve())
    if robot.get("package_dirs"):
        robot["package_dirs"] = [str((here / d).resolve()) for d in robot["package_dirs"]]
    if (raw.get("data") or {}).get("csv"):
        raw["data"]["csv"] = str((here / raw["data"]["csv"]).resolve())
    for block in raw.get("measurements") or []:
        if isinstance(block, dict) and block.get("csv"):
            block["csv"] = str((here / block["csv"]).resolve())
    if parameters:
        raw["parameters"] = {**(raw.get("parameters") or {}), **parameters}
    return yaml.safe_dump(raw, sort_keys=False).encode()


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


__all__ = ["PointStats", "point_stats", "BlockErrors", "term_errors", "subset_residual", "kfold", "edge_folds",
           "CrossValidation", "cross_validate", "setup_for_data", "portable_config", "RANGE_MARGIN", "range_excess", "posture_groups"]
