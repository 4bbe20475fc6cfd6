"""Closure rows of robocal.model.loop_rows for many anchor pairs at once.

Same formulas as `closure_rows` (c_k, and its derivatives D1, D2 with respect to a LOCAL right twist of each
anchor frame), on stacks of anchor poses (R (n, 3, 3), p (n, 3)): every sample and every closure of one kind
in one call. The point, distance and revolute kinds are whole-array numpy; the frame kind (log6 and Jlog6)
calls `closure_rows` pair by pair.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.model.lie_arrays import skew, transpose
from robocal.model.loop_rows import ROWS, Closure, closure_rows, orthonormal_pair


def hinge_bases(axes: np.ndarray) -> np.ndarray:
    """(k, 2, 3): for each revolute closure's unit axis, the two directions its misalignment is measured along."""
    return np.array([orthonormal_pair(np.asarray(a, dtype=float)) for a in axes]).reshape(-1, 2, 3)


def closure_arrays(kind: str, R1: np.ndarray, p1: np.ndarray, R2: np.ndarray, p2: np.ndarray,
                   length: np.ndarray | float = 0.0, axis: np.ndarray | None = None, basis: np.ndarray | None = None):
    """c (n, rows), D1 (n, rows, 6), D2 (n, rows, 6) at n anchor pairs of closures of one `kind`.

    length (n,) or scalar: distance kind's target; axis (n, 3) and basis (n, 2, 3) (`hinge_bases`): revolute."""
    n, rows = len(R1), ROWS[kind]
    c, D1, D2 = np.empty((n, rows)), np.zeros((n, rows, 6)), np.zeros((n, rows, 6))
    if kind == "frame":
        closure = Closure("", "frame", "", "", rows)
        for i in range(n):
            c[i], D1[i], D2[i] = closure_rows(closure, pin.SE3(R1[i], p1[i]), pin.SE3(R2[i], p2[i]))
        return c, D1, D2
    R1t = transpose(R1)
    d = p2 - p1
    if kind == "distance":
        norm = np.linalg.norm(d, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(norm[:, None] > 0, d / norm[:, None], 0.0)   # coincident points: derivative 0
        c[:, 0] = norm - length
        D1[:, 0, :3] = -np.einsum("nij,nj->ni", R1t, u)
        D2[:, 0, :3] = np.einsum("nji,nj->ni", R2, u)
        return c, D1, D2
    cp = np.einsum("nij,nj->ni", R1t, d)
    R12 = R1t @ R2
    c[:, :3] = cp
    D1[:, [0, 1, 2], [0, 1, 2]] = -1.0
    D1[:, :3, 3:] = skew(cp)
    D2[:, :3, :3] = R12
    if kind == "point":
        return c, D1, D2
    b = np.einsum("nij,nj->ni", R12, axis)        # revolute: the hinge axes stay aligned
    c[:, 3:] = np.einsum("nij,nj->ni", basis, b)
    D1[:, 3:, 3:] = basis @ skew(b)
    D2[:, 3:, 3:] = -(basis @ R12) @ skew(axis)
    return c, D1, D2
