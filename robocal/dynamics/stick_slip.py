"""Joint friction with true sticking for the simulator: Coulomb, breakaway (stiction) and viscous.

A joint at rest holds any torque up to its breakaway level F_s and stays exactly at rest; a sliding
joint feels (F_c + (F_s - F_c) exp(-(v/v_s)^2)) sign(v) + F_v v + tau_0 (the Stribeck drop from the
breakaway to the Coulomb level). Unlike `FrictionModel`'s tanh, nothing vanishes at v = 0, so a
current-based estimate at rest cannot know the friction torque: the situation of a real joint.

Time stepping (one substep dt, set-valued friction solved implicitly, as Moreau's scheme does): with
v_free the velocity the substep would give without the dry part of friction,
    v_new = argmin_v 1/2 (v - v_free)^T M (v - v_free) + dt sum_j mu_j |v_j|
mu_j = F_s on a joint at rest, the Stribeck level at its velocity otherwise. The minimiser is
maximal dissipation: joints whose holding torque stays below mu_j come out exactly at 0. It is
solved by coordinate descent (each coordinate a soft threshold; convex, converges for M > 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError
from robocal.dynamics.friction import FrictionModel


def _per_joint(value, n: int, name: str) -> np.ndarray:
    arr = np.asarray(0.0 if value is None else value, float)
    arr = np.full(n, float(arr)) if arr.ndim == 0 else arr.copy()
    if arr.shape != (n,) or not np.all(np.isfinite(arr)) or np.any(arr < 0) and name != "offset":
        raise InputError(f"stick-slip friction {name} must be {n} finite numbers >= 0, got {value}", field=name)
    return arr


@dataclass
class StickSlipFriction:
    """Per joint (n,): coulomb N m, breakaway N m (>= coulomb; the static level), viscous N m s/rad,
    stribeck_velocity rad/s (how fast the level drops from breakaway to Coulomb), offset N m."""

    coulomb: np.ndarray
    breakaway: np.ndarray | None = None
    viscous: np.ndarray | None = None
    stribeck_velocity: float | np.ndarray = 0.01
    offset: np.ndarray | None = None

    def __post_init__(self):
        n = np.atleast_1d(np.asarray(self.coulomb)).size
        self.coulomb = _per_joint(self.coulomb, n, "coulomb")
        self.breakaway = self.coulomb.copy() if self.breakaway is None else _per_joint(self.breakaway, n, "breakaway")
        self.viscous = _per_joint(self.viscous, n, "viscous")
        self.stribeck_velocity = _per_joint(self.stribeck_velocity, n, "stribeck_velocity")
        self.offset = _per_joint(self.offset, n, "offset")
        if np.any(self.breakaway < self.coulomb) or np.any(self.stribeck_velocity <= 0):
            raise InputError("breakaway must be >= coulomb and stribeck_velocity > 0", field="breakaway")

    @property
    def n(self) -> int:
        return self.coulomb.size

    def level(self, v: np.ndarray) -> np.ndarray:
        """Dry-friction magnitude (..., n) N m at velocity v: breakaway at rest, Coulomb when fast."""
        return self.coulomb + (self.breakaway - self.coulomb) * np.exp(-(np.asarray(v) / self.stribeck_velocity) ** 2)

    def torque(self, v: np.ndarray) -> np.ndarray:
        """Sliding friction (..., n) N m (0 for the dry part of a joint exactly at rest: set-valued there)."""
        v = np.asarray(v, float)
        return self.level(v) * np.sign(v) + self.viscous * v + self.offset

    def smooth_part(self, v: np.ndarray) -> np.ndarray:
        """The single-valued part, viscous and offset, applied explicitly in a substep."""
        return self.viscous * np.asarray(v, float) + self.offset

    def as_smooth_model(self, smoothing: float = 1e-3) -> FrictionModel:
        """The same friction as a `FrictionModel` (tanh of width `smoothing`): for linearisation and
        for an estimator given the true friction."""
        return FrictionModel(self.coulomb, self.viscous, self.offset, self.breakaway - self.coulomb,
                             self.stribeck_velocity, smoothing)

    def implicit_velocity(self, mass: np.ndarray, v_free: np.ndarray, v_now: np.ndarray, dt: float,
                          sweeps: int = 60, tol: float = 1e-12) -> np.ndarray:
        """End-of-substep velocity with the dry friction solved implicitly (see the module doc)."""
        mu = np.where(v_now == 0.0, self.breakaway, self.level(v_now)) * dt
        diag = np.diag(mass)
        v = np.array(v_free, float)
        for _ in range(sweeps):
            change = 0.0
            for j in range(v.size):
                # minimise over v_j: 1/2 M_jj v_j^2 + v_j (M (v - v_free))_{k != j} - ... + mu_j |v_j|
                rest = mass[j] @ (v - v_free) - diag[j] * (v[j] - v_free[j])
                target = v_free[j] - rest / diag[j]
                new = np.sign(target) * max(abs(target) - mu[j] / diag[j], 0.0)
                change = max(change, abs(new - v[j]))
                v[j] = new
            if change <= tol:
                break
        return v
