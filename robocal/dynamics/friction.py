"""Joint friction: Coulomb + viscous + offset, optionally Stribeck, per joint.

tau_f = (F_c + F_s exp(-(v/v_s)^2)) tanh(v/eps) + F_v v + tau_0     (N m, v in rad/s)

The tanh smooths the Coulomb step over |v| < eps so that the model is usable inside a
simulator and is linear in (F_c, F_v, tau_0, F_s) for fixed eps and v_s, which is what
identification uses (`regressor`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError

#: Names of the per-joint friction parameters, in regressor column order.
FRICTION_TERMS = ("coulomb", "viscous", "offset", "stribeck")


def _per_joint(value, n: int, name: str) -> np.ndarray:
    arr = np.asarray(0.0 if value is None else value, dtype=float)
    arr = np.full(n, float(arr)) if arr.ndim == 0 else arr.copy()
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise InputError(f"friction {name} must be {n} finite numbers, got shape {arr.shape}", field=name)
    return arr


@dataclass
class FrictionModel:
    """Per-joint friction for n joints (all arrays (n,)).

    coulomb N m, viscous N m s/rad, offset N m, stribeck N m (extra breakaway torque),
    stribeck_velocity rad/s, smoothing rad/s (the tanh width eps).
    """

    coulomb: np.ndarray
    viscous: np.ndarray | None = None
    offset: np.ndarray | None = None
    stribeck: np.ndarray | None = None
    stribeck_velocity: float | np.ndarray = 0.05
    smoothing: float | np.ndarray = 1e-3

    def __post_init__(self):
        n = np.atleast_1d(np.asarray(self.coulomb)).size
        self.coulomb = _per_joint(self.coulomb, n, "coulomb")
        self.viscous = _per_joint(self.viscous, n, "viscous")
        self.offset = _per_joint(self.offset, n, "offset")
        self.stribeck = _per_joint(self.stribeck, n, "stribeck")
        self.stribeck_velocity = _per_joint(self.stribeck_velocity, n, "stribeck_velocity")
        self.smoothing = _per_joint(self.smoothing, n, "smoothing")
        if np.any(self.stribeck_velocity <= 0) or np.any(self.smoothing <= 0):
            raise InputError("friction stribeck_velocity and smoothing must be > 0", field="smoothing")

    @classmethod
    def none(cls, n: int) -> "FrictionModel":
        return cls(np.zeros(n))

    @property
    def n(self) -> int:
        return self.coulomb.size

    def torque(self, velocity: np.ndarray) -> np.ndarray:
        """Friction torques (..., n) N m at joint velocities (..., n) rad/s."""
        v = np.asarray(velocity, dtype=float)
        if v.shape[-1:] != (self.n,):
            raise InputError(f"velocity must have {self.n} columns, got shape {v.shape}", field="velocity")
        sign = np.tanh(v / self.smoothing)
        breakaway = self.coulomb + self.stribeck * np.exp(-(v / self.stribeck_velocity) ** 2)
        return breakaway * sign + self.viscous * v + self.offset

    def regressor(self, velocity: np.ndarray) -> np.ndarray:
        """Per-joint basis (..., n, 4) so that torque[..., j] = regressor[..., j, :] @ params[j]."""
        v = np.asarray(velocity, dtype=float)
        if v.shape[-1:] != (self.n,):
            raise InputError(f"velocity must have {self.n} columns, got shape {v.shape}", field="velocity")
        sign = np.tanh(v / self.smoothing)
        stribeck = np.exp(-(v / self.stribeck_velocity) ** 2) * sign
        return np.stack([sign, v, np.ones_like(v), stribeck], axis=-1)

    @property
    def parameters(self) -> np.ndarray:
        """(n, 4) [coulomb, viscous, offset, stribeck] per joint."""
        return np.stack([self.coulomb, self.viscous, self.offset, self.stribeck], axis=1)

    def with_parameters(self, params: np.ndarray) -> "FrictionModel":
        """A copy with parameters (n, 4) in FRICTION_TERMS order (same eps and v_s)."""
        p = np.asarray(params, dtype=float).reshape(self.n, 4)
        return FrictionModel(p[:, 0], p[:, 1], p[:, 2], p[:, 3], self.stribeck_velocity.copy(),
                             self.smoothing.copy())

