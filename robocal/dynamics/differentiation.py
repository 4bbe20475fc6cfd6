"""Joint velocity and acceleration from sampled positions (the patent's block 711).

Schemes (all on a uniform sample period dt, s):
- "central": v_k = (q_k+1 - q_k-1)/(2 dt), a_k = (q_k+1 - 2 q_k + q_k-1)/dt^2. Truncation error
  |dv| <= dt^2/6 max|q'''|, |da| <= dt^2/12 max|q''''|; noise gain 1/(sqrt(2) dt) and 2/dt^2 x
  sigma_q. The two end samples use second-order one-sided stencils.
- "backward": causal first-order stencils; error dt/2 max|q''| (velocity), dt max|q'''|.
  Lag makes it far worse than "central" (spec test E6); offered for comparison.
- "savgol": Savitzky-Golay smoothing derivative (scipy), for noisy logs; window and order given.
Per control tick, `TickDifferentiator` gives the central estimate one tick late (it needs the
next sample), or the backward estimate without delay.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from robocal.errors import InputError
from scipy.signal import savgol_filter

SCHEMES = ("central", "backward", "savgol")


def differentiate(positions: np.ndarray, dt: float, scheme: str = "central", window: int = 9,
                  order: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Velocities and accelerations of a position log.

    positions (T, n) rad; dt s. Returns v (T, n) rad/s and a (T, n) rad/s^2, aligned with the
    input samples. `window` and `order` are used by "savgol" only.
    """
    q = np.asarray(positions, dtype=float)
    if q.ndim != 2 or q.shape[0] < 3:
        raise InputError(f"positions must be (T, n) with T >= 3, got shape {q.shape}", field="positions")
    if not dt > 0:
        raise InputError(f"sample period must be > 0, got {dt}", field="dt")
    if scheme == "central":
        return _central(q, dt)
    if scheme == "backward":
        return _backward(q, dt)
    if scheme == "savgol":
        if window % 2 == 0 or window <= order or window > q.shape[0]:
            raise InputError(f"savgol window must be odd, > order and <= samples; got {window}",
                             field="window")
        v = savgol_filter(q, window, order, deriv=1, delta=dt, axis=0, mode="interp")
        a = savgol_filter(q, window, order, deriv=2, delta=dt, axis=0, mode="interp")
        return v, a
    raise InputError(f"unknown differentiation scheme '{scheme}'; known: {', '.join(SCHEMES)}",
                     field="scheme")


def _central(q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    v = np.empty_like(q)
    a = np.empty_like(q)
    v[1:-1] = (q[2:] - q[:-2]) / (2 * dt)
    a[1:-1] = (q[2:] - 2 * q[1:-1] + q[:-2]) / dt**2
    # second-order one-sided stencils at the ends
    v[0] = (-3 * q[0] + 4 * q[1] - q[2]) / (2 * dt)
    v[-1] = (3 * q[-1] - 4 * q[-2] + q[-3]) / (2 * dt)
    if q.shape[0] >= 4:
        a[0] = (2 * q[0] - 5 * q[1] + 4 * q[2] - q[3]) / dt**2
        a[-1] = (2 * q[-1] - 5 * q[-2] + 4 * q[-3] - q[-4]) / dt**2
    else:
        a[0] = a[-1] = a[1]
    return v, a


def _backward(q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    v = np.empty_like(q)
    a = np.empty_like(q)
    v[1:] = (q[1:] - q[:-1]) / dt
    v[0] = v[1]
    a[2:] = (q[2:] - 2 * q[1:-1] + q[:-2]) / dt**2
    a[:2] = a[2]
    return v, a


class TickDifferentiator:
    """Differentiate positions one sample at a time (inside the 4 ms loop).

    `push(q)` returns (q_k, v_k, a_k) for the newest sample that can be estimated: with
    "central" that is the previous sample (one tick of delay), with "backward" the current one.
    Returns None until enough samples have arrived (3).
    """

    def __init__(self, dt: float, scheme: str = "central"):
        if scheme not in ("central", "backward"):
            raise InputError("per-tick differentiation supports 'central' and 'backward'", field="scheme")
        if not dt > 0:
            raise InputError(f"sample period must be > 0, got {dt}", field="dt")
        self.dt, self.scheme = float(dt), scheme
        self._last: deque[np.ndarray] = deque(maxlen=3)

    @property
    def delay_samples(self) -> int:
        return 1 if self.scheme == "central" else 0

    def push(self, q: np.ndarray):
        self._last.append(np.array(q, dtype=float))
        if len(self._last) < 3:
            return None
        q0, q1, q2 = self._last
        acc = (q2 - 2 * q1 + q0) / self.dt**2
        if self.scheme == "central":
            return q1, (q2 - q0) / (2 * self.dt), acc
        return q2, (q2 - q1) / self.dt, acc
