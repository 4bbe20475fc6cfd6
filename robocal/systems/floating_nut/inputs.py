"""Checks of the poses and strut lengths given to the floating-nut kinematics: a clear error per bad row."""
from __future__ import annotations

import math

import numpy as np

from robocal.errors import InputError
from robocal.systems.floating_nut.geometry import N_LEGS

def as_poses(poses) -> tuple[np.ndarray, bool]:
    try:
        arr = np.asarray(poses, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"poses must be numbers: {exc}", field="pose") from exc
    single = arr.ndim == 1
    arr = np.atleast_2d(arr)
    if arr.ndim != 2 or arr.shape[1] != 6:
        raise InputError(f"poses must have shape (6,) or (N, 6) [x y z alpha beta gamma], got "
                         f"{np.shape(poses)}", field="pose")
    bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
    if bad.size:
        raise InputError(f"pose {bad[0]} has non-finite entries", row=int(bad[0]), field="pose")
    return arr, single


def as_lengths(lengths) -> tuple[np.ndarray, bool]:
    arr = np.asarray(lengths, dtype=float)
    single = arr.ndim == 1
    arr = np.atleast_2d(arr)
    if arr.ndim != 2 or arr.shape[1] != N_LEGS:
        raise InputError(f"lengths must have shape (6,) or (N, 6), got {np.shape(lengths)}", field="lengths")
    bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
    if bad.size:
        raise InputError(f"length set {bad[0]} has non-finite entries", row=int(bad[0]), field="lengths")
    return arr, single


def single_pose_inputs(lengths, p_init):
    """(lengths (6,), p_init (6,) or None) as floats when both are one finite pose, else None (the
    batch path then handles them, and reports bad input)."""
    L = np.asarray(lengths, dtype=float)
    if L.shape != (N_LEGS,) or not math.isfinite(sum(L.tolist())):
        return None
    if p_init is None:
        return L, None
    p = np.asarray(p_init, dtype=float)
    if p.shape != (6,) or not math.isfinite(sum(p.tolist())):
        return None
    return L, p.tolist()
