"""One loop closure of a closed chain and its constraint rows.

Kinds (rows): point 3 (two anchor points coincide), frame 6 (two anchor frames coincide), distance 1 (two
anchor points at a fixed distance), revolute 5 (points coincide, hinge axes aligned). Derivatives are
taken with respect to a LOCAL right twist xi = [v; w] of each anchor frame (M <- M exp6(xi)).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from robocal.model.lie_arrays import skew

ROWS = {"point": 3, "frame": 6, "distance": 1, "revolute": 5}


@dataclass(frozen=True)
class Closure:
    """One loop closure between frames `frame1` and `frame2` (names of Pinocchio frames).

    kind    "point" | "frame" | "distance" | "revolute"
    rows    number of constraint rows
    length  target distance (m) for the distance kind, else 0
    axis    (3,) unit hinge axis in the frame1 anchor frame (revolute kind), else None
    """

    name: str
    kind: str
    frame1: str
    frame2: str
    rows: int
    length: float = 0.0
    axis: tuple | None = None


def orthonormal_pair(a: np.ndarray) -> np.ndarray:
    """(2, 3): two unit vectors orthogonal to unit `a` and to each other."""
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    e1 = np.cross(a, helper)
    e1 /= np.linalg.norm(e1)
    return np.vstack([e1, np.cross(a, e1)])


def closure_rows(closure: Closure, M1: pin.SE3, M2: pin.SE3):
    """(c_k, D1_k, D2_k) of one closure; see LoopSet.closure_error."""
    R1, R2 = M1.rotation, M2.rotation
    kind = closure.kind
    if kind == "frame":
        M12 = M1.actInv(M2)
        jl = pin.Jlog6(M12)
        return pin.log6(M12).vector, -jl @ M12.inverse().action, jl
    d = M2.translation - M1.translation
    if kind == "distance":
        n = np.linalg.norm(d)
        u = d / n if n > 0 else np.zeros(3)  # coincident points: no direction, derivative 0
        d1, d2 = np.zeros((1, 6)), np.zeros((1, 6))
        d1[0, :3] = -(R1.T @ u)
        d2[0, :3] = R2.T @ u
        return np.array([n - closure.length]), d1, d2
    cp = R1.T @ d
    R12 = R1.T @ R2
    d1 = np.zeros((ROWS[kind], 6))
    d2 = np.zeros((ROWS[kind], 6))
    d1[:3, :3] = -np.eye(3)
    d1[:3, 3:] = skew(cp)
    d2[:3, :3] = R12
    if kind == "point":
        return cp, d1, d2
    # revolute: point rows + the hinge axes stay aligned (two components of R12 a across a)
    a = np.asarray(closure.axis)
    E = orthonormal_pair(a)
    b = R12 @ a
    d1[3:, 3:] = E @ skew(b)
    d2[3:, 3:] = -E @ R12 @ skew(a)
    return np.concatenate([cp, E @ b]), d1, d2
