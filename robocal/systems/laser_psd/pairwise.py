"""The patent's objective (see docs/laser_psd.md): pairwise beam "intersections".

For every eligible pair of beams (i, j) the midpoint P_k of their common perpendicular is taken as their
intersection; the residual of pair k is P_k - mean(P), zero exactly when all beams meet in one point.
Kept for comparison with the point-to-line residual (robocal.residuals.laser_line), which needs no pair
skipping and does not magnify noise on pairs that cross at a small angle.

Derivative of a midpoint: the feet Q_i = o_i + s u_i, Q_j = o_j + t u_j satisfy u_i.g = u_j.g = 0 with
g = Q_i - Q_j; differentiating these two conditions gives ds, dt (implicit function theorem).
"""
from __future__ import annotations

import numpy as np

from robocal.model.lie_arrays import skew
from robocal.residuals.base import Residual, Term, point_jacobian


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def closest_points(o1, u1, o2, u2, min_angle: float = np.radians(2.0)):
    """(midpoint, gap, s, t) of the common perpendicular of two lines, or None when they are within
    `min_angle` of parallel (the midpoint is then ill-defined)."""
    u1, u2 = _unit(u1), _unit(u2)
    w = np.asarray(o1, float) - np.asarray(o2, float)
    b = u1 @ u2
    if np.sqrt(max(0.0, 1.0 - b * b)) < np.sin(min_angle):
        return None
    d, e, D = u1 @ w, u2 @ w, 1.0 - b * b
    s, t = (b * e - d) / D, (e - b * d) / D
    q1, q2 = o1 + s * u1, o2 + t * u2
    return (q1 + q2) / 2, float(np.linalg.norm(q1 - q2)), float(s), float(t)


def eligible_pairs(directions, min_angle: float = np.radians(2.0)) -> list[tuple[int, int]]:
    """Pairs (i < j) of beams at least `min_angle` apart (spec 6.5: skip near-parallel pairs)."""
    U = np.array([_unit(u) for u in directions])
    out = []
    for i in range(len(U)):
        for j in range(i + 1, len(U)):
            if np.sqrt(max(0.0, 1.0 - (U[i] @ U[j]) ** 2)) >= np.sin(min_angle):
                out.append((i, j))
    return out


def lsq_point(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    """The point nearest to all lines in least squares, c = [sum (I - u u^T)]^-1 sum (I - u u^T) o,
    and each line's distance to it."""
    A, y, projs = np.zeros((3, 3)), np.zeros(3), []
    for o, u in zip(origins, directions):
        u = _unit(u)
        P = np.eye(3) - np.outer(u, u)
        A += P
        y += P @ o
        projs.append(P)
    c = np.linalg.solve(A, y)
    dists = np.array([np.linalg.norm(P @ (c - o)) for P, o in zip(projs, origins)])
    return c, dists


class PairwiseScatterResidual(Residual):
    """Term k: P_k - mean(P) over the given pairs of samples (3 rows). The beam is fixed on `frame`:
    origin and unit direction in that frame (the laser mount is known here; no auxiliary unknowns)."""

    type_name = "laser_pairwise"
    observed = False
    dim = 3
    row_units = ("length", "length", "length")

    def __init__(self, name, frame, pairs, origin=(0.0, 0.0, 0.0), direction=(0.0, 0.0, 1.0), sigma=1e-5):
        self.pairs = [(int(i), int(j)) for i, j in pairs]
        if not self.pairs:
            raise ValueError(f"residual '{name}': no pair of beams to intersect")
        super().__init__(name, [i for i, _ in self.pairs], sigma)
        self.frame = frame
        self.origin = np.asarray(origin, dtype=float).reshape(3)
        self.direction = _unit(direction)
        self.used = sorted({s for p in self.pairs for s in p})
        self._cache = (None, None)

    def term_samples(self, k):
        return tuple(self.used)   # the centroid makes every term depend on every beam

    def _beam(self, state):
        M = state.pose(self.frame)
        R = M.rotation
        o, u = M.act(self.origin), R @ self.direction
        do = point_jacobian(M, self.origin)                          # (3, 6) per LOCAL twist
        du = np.hstack([np.zeros((3, 3)), -R @ skew(self.direction)])
        return o, u, do, du

    def _midpoints(self, states):
        if self._cache[0] is states:
            return self._cache[1]
        beams = {s: self._beam(states[s]) for s in self.used}
        P, dP = [], []
        for i, j in self.pairs:
            oi, ui, doi, dui = beams[i]
            oj, uj, doj, duj = beams[j]
            w, b = oi - oj, ui @ uj
            D = 1.0 - b * b
            s, t = (b * (uj @ w) - ui @ w) / D, ((uj @ w) - b * (ui @ w)) / D
            g = w + s * ui - t * uj
            # columns: [twist of beam i (6) | twist of beam j (6)]
            dOi, dUi = np.hstack([doi, 0 * doi]), np.hstack([dui, 0 * dui])
            dOj, dUj = np.hstack([0 * doj, doj]), np.hstack([0 * duj, duj])
            dw = dOi - dOj
            rhs = -np.vstack([g @ dUi + ui @ dw - t * (ui @ dUj),
                              g @ dUj + uj @ dw + s * (uj @ dUi)])
            ds, dt = np.linalg.solve(np.array([[1.0, -b], [b, -1.0]]), rhs)
            P.append((oi + s * ui + oj + t * uj) / 2)
            dP.append((dOi + np.outer(ui, ds) + s * dUi + dOj + np.outer(uj, dt) + t * dUj) / 2)
        P = np.array(P)
        mean_d = {s: np.zeros((3, 6)) for s in self.used}
        for (i, j), d in zip(self.pairs, dP):
            mean_d[i] += d[:, :6] / len(self.pairs)
            mean_d[j] += d[:, 6:] / len(self.pairs)
        out = (P, P.mean(axis=0), dP, mean_d)
        self._cache = (states, out)    # holding `states` keeps its id from being reused
        return out

    def evaluate(self, k, states, aux):
        P, Pbar, dP, mean_d = self._midpoints(states)
        i, j = self.pairs[k]
        frames = []
        for s in self.used:
            D = -mean_d[s]
            if s == i:
                D = D + dP[k][:, :6]
            elif s == j:
                D = D + dP[k][:, 6:]
            frames.append((s, self.frame, D))
        return Term(P[k] - Pbar, frames, None)

    def midpoints(self, states) -> np.ndarray:
        """(M, 3) the pairwise midpoints at the given states (the PSD centre estimate is their mean)."""
        return self._midpoints(states)[0]
