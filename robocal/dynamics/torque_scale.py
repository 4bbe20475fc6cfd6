"""The torque-constant scale from the gravity change along a constant-speed approach in free space.

A current-based estimate with torque constants off by a factor (1 + e) reads the external joint
torques as c = e (g(q) + f(v) + ...) + (f(v) - f_hat(v)) + (1 + e) J^T F; in free space F = 0. At
constant joint speed the friction terms are constant, so along the approach each joint's c changes
only through gravity: c_j(t) = e g_j(q(t)) + b_j (b_j the joint's constant friction and model error).
A least-squares line of c_j against the model's g_j, with an intercept per joint, gives e whatever
the friction error; its information is the spread of g_j along the approach (for the UR5 of
examples/force_deburring.py, joint 2's gravity torque changes by 2.6 N m over the 30 mm approach).
The estimate is combined with the prior knowledge of the torque constants (a tolerance taken as
2 sigma) as two Gaussian measurements, so a short or gravity-neutral approach leaves the nominal
constants. The scale needs the model's masses: an inertial model identified with the same wrong
torque constants carries the same scale (the equations are homogeneous) and gives e = 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError


@dataclass(frozen=True)
class ScaleEstimate:
    """scale: the factor to divide current-based torques by (1 + e, after the prior); raw: e from the
    data alone; raw_std: its standard deviation (inf when the data carry none); std: of the scale
    after the prior; joints: those whose samples entered; samples: how many per joint."""

    scale: float
    raw: float
    raw_std: float
    std: float
    joints: tuple[int, ...]
    samples: tuple[int, ...]


def torque_scale(torque: np.ndarray, gravity: np.ndarray, velocity: np.ndarray, cruise: np.ndarray,
                 speed_band: float = 0.1, tolerance: float = 0.05, min_samples: int = 10) -> ScaleEstimate:
    """torque (N, n) the external joint torques of the estimate, gravity (N, n) the model's g(q) at the
    same samples, velocity (N, n), cruise (n,) the approach's joint speeds rad/s. A joint's sample is
    used when its velocity is within speed_band x |cruise| of cruise (constant speed: friction
    constant); tolerance is the torque constants' relative tolerance (the prior, as 2 sigma)."""
    torque, gravity, velocity = (np.atleast_2d(np.asarray(a, float)) for a in (torque, gravity, velocity))
    cruise = np.asarray(cruise, float)
    if not (torque.shape == gravity.shape == velocity.shape and cruise.shape == torque.shape[1:]):
        raise InputError("torque, gravity and velocity must be (N, n) and cruise (n,)", field="torque")
    if not (0 < speed_band < 1 and tolerance > 0):
        raise InputError("speed_band must lie in (0, 1) and tolerance be > 0", field="speed_band")
    cross = info = 0.0
    joints, counts = [], []
    for j in range(torque.shape[1]):
        keep = (np.abs(velocity[:, j] - cruise[j]) <= speed_band * abs(cruise[j])) & (cruise[j] != 0)
        if keep.sum() < min_samples:
            continue
        g = gravity[keep, j] - gravity[keep, j].mean()
        c = torque[keep, j] - torque[keep, j].mean()
        spread = g @ g
        if spread <= 1e-12 * max(1.0, float(np.abs(gravity[keep, j]).max()) ** 2) * keep.sum():
            continue                              # gravity does not change: no information on e
        slope = (g @ c) / spread
        var = float(np.sum((c - slope * g) ** 2)) / (keep.sum() - 2)
        if var <= 0:
            continue
        cross += (g @ c) / var
        info += spread / var
        joints.append(j)
        counts.append(int(keep.sum()))
    prior_var = (tolerance / 2.0) ** 2
    if info <= 0:
        return ScaleEstimate(1.0, 0.0, float("inf"), float(np.sqrt(prior_var)), (), ())
    raw, raw_var = cross / info, 1.0 / info
    post_var = 1.0 / (1.0 / prior_var + 1.0 / raw_var)
    return ScaleEstimate(float(1.0 + raw * post_var / raw_var), float(raw), float(np.sqrt(raw_var)),
                         float(np.sqrt(post_var)), tuple(joints), tuple(counts))
