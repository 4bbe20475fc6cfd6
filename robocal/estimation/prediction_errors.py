"""Prediction − measurement of every term of a problem at given parameter values, and its norms.

`term_errors(problem, params)` evaluates every residual term of `problem` with the values of `params` (a
fitted ParameterSet, typically from another problem with the same residual names), without a fit:
prediction - measurement, SI units, every row (also rows of weight 0). Point-like blocks (all rows
lengths, three per point: point, rigid_points) are scored per point: RMSE per axis, RMSE of the norm, and
the largest norm, in mm (`BlockErrors.point_stats`). `norm_errors(block)` turns one block's errors into
norms per point / orientation (mm, mrad). See docs/validation.md.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from robocal.errors import InputError
from robocal.estimation.problem import Problem
from robocal.estimation.sessions import corrections, session_arrays
from robocal.model.batch_kinematics import BatchKinematics, supports_batch
from robocal.model.kinematics import ModelState
from robocal.model.parameters import ParameterSet
from robocal.residuals.base import Residual

MM = 1e3
UNITS = {"length": (1e3, "mm", "3D position error"), "angle": (1e3, "mrad", "3D orientation error"),
         "pixel": (1.0, "px", "2D reprojection error")}
#: rows of one kind that form one vector: a 3D point or rotation, a pixel's (u, v)
GROUP = {"pixel": 2}


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
    states, batch = None, None
    out = {}
    for res in residuals:
        names = [p.name for p in res.aux_parameters()]
        missing = [n for n in names if n not in params]
        if missing:
            raise InputError(f"the parameters lack the set-up quantities of block '{res.name}': "
                             f"{', '.join(missing)}")
        aux = np.array([params[n].value for n in names])
        if res.batched and res.n_terms and supports_batch(ms):
            # every term at once from the frame's poses, as Problem.evaluate's batched pass computes them
            batch = batch or BatchKinematics(ms, problem.sample_constants(ms), problem.values, problem.directions)
            raw = batched_errors(problem, batch, res, aux)
        else:
            states = states or problem.states(ms)
            raw = np.array([res.evaluate(k, states, aux).r for k in range(res.n_terms)]).reshape(res.n_terms,
                                                                                                  res.dim)
        out[res.name] = BlockErrors(res.name, res.type_name, np.asarray(res.samples).copy(), raw,
                                    tuple(res.row_units), _labels(res))
    return out

def batched_errors(problem: Problem, batch, res, aux) -> np.ndarray:
    """(n_terms, dim) prediction - measurement of a batched residual, its frame's poses from `batch` (in each
    sample's session frame when sessions are re-registered, at the problem's own corrections, as
    Problem.states places them)."""
    fa = batch.frame(res.frame, res.samples, jacobian=False)
    R, p = fa.R, fa.p
    if problem.sessions is not None and problem.sessions.corrected:
        R, p = session_arrays(R, p, corrections(problem.sessions, problem.params),
                              problem.sessions.of_sample[res.samples])
    return np.asarray(res.evaluate_batch(slice(0, res.n_terms), R, p, aux).r).reshape(res.n_terms, res.dim)


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


def norm_errors(block: BlockErrors) -> dict[str, np.ndarray]:
    """{unit kind: (n_terms, k) error norms in mm / mrad}: triples of rows of one kind -> 3D norm, else |row|."""
    units = np.array(block.row_units)
    out = {}
    for kind in dict.fromkeys(block.row_units):
        scale = UNITS.get(kind, (1.0, kind, kind))[0]
        cols = block.raw[:, units == kind] * scale
        g = GROUP.get(kind, 3)
        out[kind] = (np.linalg.norm(cols.reshape(len(cols), -1, g), axis=2) if cols.shape[1] % g == 0
                     else np.abs(cols))
    return out

def norm_rms(values: np.ndarray) -> dict:
    v = np.asarray(values, float).reshape(-1)
    if not len(v):
        return {"n": 0, "rms_norm": None, "max_norm": None}
    return {"n": int(len(v)), "rms_norm": float(np.sqrt(np.mean(v ** 2))), "max_norm": float(np.max(v))}

def primary_errors(blocks: dict[str, BlockErrors]) -> tuple[np.ndarray, np.ndarray, str]:
    """(samples, norms) of every length point of every block (mm) or, without lengths, of the angles (mrad), or
    without either, of the pixels (px)."""
    for kind in ("length", "angle", "pixel"):
        samples, norms = [], []
        for b in blocks.values():
            e = norm_errors(b).get(kind)
            if e is not None:
                samples.append(np.repeat(b.samples[:, None], e.shape[1], 1).reshape(-1) if b.samples.ndim == 1
                               else np.repeat(b.samples[:, :1], e.shape[1], 1).reshape(-1))
                norms.append(e.reshape(-1))
        if norms:
            return np.concatenate(samples), np.concatenate(norms), UNITS[kind][1]
    raise InputError("no length, angle or pixel measurement to score")
