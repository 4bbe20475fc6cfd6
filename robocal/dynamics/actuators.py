"""Actuator model: motor currents <-> joint torques.

Per motor j: torque constant K_t,j (N m/A, motor side), gear ratio N_j (motor turns per
joint turn) and current-sensor offset I0_j (A). Motor-side torques, after the gear, are
tau_m,j = N_j K_t,j (I_j - I0_j). A coupling matrix C (n x n) maps them to joint torques,
tau = C @ tau_m; it is the identity for independent axes and has off-diagonal terms for a
coupled wrist (by power balance C = G^-T when joint angles are q = G @ motor angles).
The patent's diagonal K_t is the special case C = I, diag(N_j K_t,j).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robocal.errors import InputError


def _vector(value, n: int, name: str, default: float) -> np.ndarray:
    if value is None:
        return np.full(n, float(default))
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be {n} finite numbers, got shape {arr.shape}", field=name)
    return arr.copy()


@dataclass
class ActuatorModel:
    """Currents to joint torques for n joints, both ways.

    torque_constant  (n,) N m/A, motor side
    gear_ratio       (n,) dimensionless, motor turns per joint turn
    current_offset   (n,) A, subtracted from every reading
    coupling         (n, n) joint torques = coupling @ motor-side torques (identity if None)
    """

    torque_constant: np.ndarray
    gear_ratio: np.ndarray | None = None
    current_offset: np.ndarray | None = None
    coupling: np.ndarray | None = None
    _gain: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        kt = np.atleast_1d(np.asarray(self.torque_constant, dtype=float))
        n = kt.size
        self.torque_constant = _vector(kt, n, "torque_constant", 1.0)
        self.gear_ratio = _vector(self.gear_ratio, n, "gear_ratio", 1.0)
        self.current_offset = _vector(self.current_offset, n, "current_offset", 0.0)
        if np.any(self.torque_constant * self.gear_ratio == 0.0):
            raise InputError("torque_constant * gear_ratio must be non-zero on every joint",
                             field="torque_constant")
        if self.coupling is None:
            self.coupling = np.eye(n)
        self.coupling = np.asarray(self.coupling, dtype=float)
        if self.coupling.shape != (n, n) or not np.all(np.isfinite(self.coupling)):
            raise InputError(f"coupling must be a finite {n}x{n} matrix, got {self.coupling.shape}",
                             field="coupling")
        if np.linalg.cond(self.coupling) > 1e12:
            raise InputError("coupling matrix is singular: currents cannot be synthesised", field="coupling")
        self.refresh()

    def refresh(self) -> None:
        """Recompute the cached gain matrix after editing a parameter in place."""
        self._gain = self.coupling * (self.gear_ratio * self.torque_constant)[None, :]

    @classmethod
    def identity(cls, n: int) -> "ActuatorModel":
        """Unit torque constants: currents are joint torques (useful for torque-sensing robots)."""
        return cls(np.ones(n))

    @property
    def n(self) -> int:
        return self.torque_constant.size

    @property
    def gain(self) -> np.ndarray:
        """(n, n) N m/A: tau = gain @ (I - I0). The patent's K_t when the coupling is identity."""
        return self._gain

    def torque(self, current: np.ndarray) -> np.ndarray:
        """Joint torques (..., n) N m from currents (..., n) A (one sample or a whole log)."""
        current = np.asarray(current, dtype=float)
        self._check(current, "current")
        return (current - self.current_offset) @ self._gain.T

    def current(self, torque: np.ndarray) -> np.ndarray:
        """Currents (..., n) A that produce joint torques (..., n) N m (synthesising data)."""
        torque = np.asarray(torque, dtype=float)
        self._check(torque, "torque")
        return np.linalg.solve(self._gain, torque.reshape(-1, self.n).T).T.reshape(torque.shape) \
            + self.current_offset

    def _check(self, arr: np.ndarray, name: str) -> None:
        if arr.shape[-1:] != (self.n,):
            raise InputError(f"{name} must have {self.n} columns (one per joint), got shape {arr.shape}",
                             field=name)
