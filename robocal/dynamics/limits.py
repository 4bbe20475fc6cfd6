"""Velocity and acceleration limits projected onto the path parameter (spec §4-C, block 460).

Cartesian (corrected Eqs. 5-6), with f' = df/ds and f'' = d2f/ds2:
    sd_max  = min(v_max/|f'|, c sqrt(a_max/|f''|))            (sqrt term = inf when f'' = 0)
    sdd_max = (a_max - |f''| sd_max^2) / |f'|
so |sd| <= sd_max and |sdd| <= sdd_max imply |f' sd| <= v_max and |f' sdd + f'' sd^2| <= a_max.
Per joint axis with h' = dq/ds, h'' (spec §11.2 item 8):
    sd_max  = min_j min(qd_max_j/|h'_j|, c sqrt(qdd_max_j/|h''_j|))
    sdd_max = min_j (qdd_max_j - |h''_j| sd_max^2)/|h'_j|
Orientation rate (optional, not in the patent), with w' = d(omega)/ds and w'' (rad, world axes):
the same pair as the Cartesian one with w_max rad/s and dw_max rad/s^2 in place of v_max, a_max.
A pure reorientation (|f'| = 0) stays invalid: the force regulator needs a tangent.
Several constraints share one sd_max (the smallest); every sdd_max is then evaluated with it.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError


def check_c(c: float) -> float:
    if not 0.0 < c < 1.0:
        raise InputError(f"the limit constant c must lie in (0, 1), got {c}", field="c")
    return float(c)


def _ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """num/den with den = 0 -> +inf (no constraint)."""
    out = np.full(np.broadcast(num, den).shape, np.inf)
    np.divide(num, den, out=out, where=den > 0)
    return out


def project_limits(df: np.ndarray, ddf: np.ndarray, v_max: float, a_max: float, c: float,
                   dh: np.ndarray | None = None, ddh: np.ndarray | None = None,
                   qd_max: np.ndarray | None = None, qdd_max: np.ndarray | None = None,
                   dw: np.ndarray | None = None, ddw: np.ndarray | None = None,
                   w_max: float | None = None, dw_max: float | None = None) -> tuple[float, float]:
    """(sd_max 1/s, sdd_max 1/s^2) at one s from Cartesian limits and optional joint and
    orientation-rate limits.

    df, ddf (3,) m: path derivatives in s; v_max m/s, a_max m/s^2; dh, ddh (n,) rad: joint-path
    derivatives in s with per-axis limits qd_max rad/s, qdd_max rad/s^2 (all four or none);
    dw, ddw (3,) rad: the tool's angular rate and its derivative in s, with w_max rad/s and
    dw_max rad/s^2 (all four or none). Raises InputError if |f'| = 0 (no tangent).
    """
    c = check_c(c)
    if not (v_max > 0 and a_max > 0):
        raise InputError(f"v_max and a_max must be > 0, got {v_max}, {a_max}", field="v_max")
    nf1, nf2 = float(np.linalg.norm(df)), float(np.linalg.norm(ddf))
    if nf1 <= 0.0:
        raise InputError("path tangent is zero: limits cannot be projected", field="position")
    sd_max = min(v_max / nf1, c * np.sqrt(a_max / nf2) if nf2 > 0 else np.inf)
    joints = dh is not None
    if joints:
        h1, h2 = np.abs(np.asarray(dh, float)), np.abs(np.asarray(ddh, float))
        qd, qdd = np.asarray(qd_max, float), np.asarray(qdd_max, float)
        if np.any(qd <= 0) or np.any(qdd <= 0):
            raise InputError("joint velocity and acceleration limits must be > 0", field="qd_max")
        sd_max = min(sd_max, float(np.min(_ratio(qd, h1))), float(np.min(c * np.sqrt(_ratio(qdd, h2)))))
    turning = dw is not None
    if turning:
        if not (w_max is not None and dw_max is not None and w_max > 0 and dw_max > 0):
            raise InputError("orientation-rate limits w_max and dw_max must both be > 0", field="w_max")
        nw1, nw2 = float(np.linalg.norm(dw)), float(np.linalg.norm(ddw))
        sd_max = min(sd_max, float(_ratio(np.float64(w_max), np.float64(nw1))),
                     float(c * np.sqrt(_ratio(np.float64(dw_max), np.float64(nw2)))))
    sdd_max = (a_max - nf2 * sd_max**2) / nf1
    if turning and nw1 > 0:
        sdd_max = min(sdd_max, (dw_max - nw2 * sd_max**2) / nw1)
    if joints:
        sdd_max = min(sdd_max, float(np.min(_ratio(qdd - h2 * sd_max**2, h1))))
    return float(sd_max), float(sdd_max)
