"""Where q, v, a for the dynamic model come from (the patent's block 711): measured positions
differentiated numerically, or the setpoints and their own derivatives. The choice and the scheme
travel with the data so that a result can say how it was obtained."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError
from robocal.dynamics.differentiation import differentiate


@dataclass
class JointState:
    """q (T, nq) rad, v and a (T, nv) rad/s, rad/s^2; source 'measured' or 'setpoint';
    scheme: how v and a were obtained ('central', 'savgol', 'analytic', ...)."""

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    source: str
    scheme: str


def from_measurements(q_mes: np.ndarray, dt: float, scheme: str = "central", **options) -> JointState:
    """Differentiate measured positions (T, n) sampled every dt s (see differentiation.py)."""
    q = np.asarray(q_mes, dtype=float)
    v, a = differentiate(q, dt, scheme, **options)
    return JointState(q, v, a, "measured", scheme)


def from_setpoints(q_des: np.ndarray, dt: float, v_des: np.ndarray | None = None,
                   a_des: np.ndarray | None = None, scheme: str = "central") -> JointState:
    """Setpoints (T, n); their analytic derivatives when given, else differentiated with `scheme`."""
    q = np.asarray(q_des, dtype=float)
    if (v_des is None) != (a_des is None):
        raise InputError("give both setpoint velocities and accelerations, or neither", field="v_des")
    if v_des is None:
        v, a = differentiate(q, dt, scheme)
        return JointState(q, v, a, "setpoint", scheme)
    v, a = np.asarray(v_des, dtype=float), np.asarray(a_des, dtype=float)
    if v.shape != q.shape or a.shape != q.shape:
        raise InputError(f"setpoint derivatives must be {q.shape}", field="v_des")
    return JointState(q, v, a, "setpoint", "analytic")
