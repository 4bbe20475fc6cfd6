"""Excitation trajectories for dynamic identification: finite Fourier series (Swevers et al.).

q_j(t) = c_j + sum_l [ a_jl/(l w) sin(l w t) - b_jl/(l w) cos(l w t) ],  w = 2 pi f_base
is periodic with period 1/f_base, so a log can be averaged over periods, and has exact
derivatives. Random coefficients (seeded) are scaled down until every joint stays inside its
position range (with a margin) and below its velocity and acceleration limits.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError


@dataclass
class FourierTrajectory:
    """centre (n,) rad; a, b (n, H) rad/s (velocity amplitudes per harmonic); base_frequency Hz."""

    centre: np.ndarray
    a: np.ndarray
    b: np.ndarray
    base_frequency: float

    @property
    def period(self) -> float:
        return 1.0 / self.base_frequency

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, v, a at times t (T,) s, each (T, n) in rad, rad/s, rad/s^2."""
        t = np.asarray(t, float)
        w = 2 * np.pi * self.base_frequency
        lw = w * np.arange(1, self.a.shape[1] + 1)          # (H,)
        s, c = np.sin(np.outer(t, lw)), np.cos(np.outer(t, lw))   # (T, H)
        q = self.centre + s @ (self.a / lw).T - c @ (self.b / lw).T
        v = c @ self.a.T + s @ self.b.T
        acc = -(s * lw) @ self.a.T + (c * lw) @ self.b.T
        return q, v, acc


def fourier_excitation(lower: np.ndarray, upper: np.ndarray, qd_max: np.ndarray, qdd_max: np.ndarray,
                       rng: np.random.Generator, base_frequency: float = 0.1, harmonics: int = 5,
                       margin: float = 0.1, centre: np.ndarray | None = None) -> FourierTrajectory:
    """A random Fourier trajectory inside [lower + margin, upper - margin] (rad), |v| <= qd_max,
    |a| <= qdd_max (checked on a fine grid over one period; all arrays (n,))."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    qd_max, qdd_max = np.asarray(qd_max, float), np.asarray(qdd_max, float)
    lo, hi = lower + margin, upper - margin
    if np.any(hi <= lo) or np.any(qd_max <= 0) or np.any(qdd_max <= 0):
        raise InputError("joint range (after margin) and velocity/acceleration limits must be positive",
                         field="limits")
    if not (base_frequency > 0 and harmonics >= 1):
        raise InputError("base_frequency must be > 0 and harmonics >= 1", field="base_frequency")
    n = lower.size
    c = (lo + hi) / 2 if centre is None else np.asarray(centre, float)
    if np.any(c <= lo) or np.any(c >= hi):
        raise InputError("excitation centre must lie strictly inside the joint range", field="centre")
    a, b = rng.normal(size=(n, harmonics)), rng.normal(size=(n, harmonics))
    traj = FourierTrajectory(c, a, b, base_frequency)
    t = np.linspace(0, traj.period, 400 * harmonics, endpoint=False)
    q, v, acc = traj.sample(t)
    dev = q - c
    # q - c, v and a are linear in the coefficients: one common scale per joint fits all limits
    scale = np.min(np.stack([
        np.where(dev.max(0) > 0, (hi - c) / np.maximum(dev.max(0), 1e-300), np.inf),
        np.where(dev.min(0) < 0, (lo - c) / np.minimum(dev.min(0), -1e-300), np.inf),
        qd_max / np.abs(v).max(0), qdd_max / np.abs(acc).max(0)]), axis=0) * 0.98
    return FourierTrajectory(c, a * scale[:, None], b * scale[:, None], base_frequency)
