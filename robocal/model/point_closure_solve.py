"""Newton steps and C_s^-1 of a closed chain whose point closures each own two solved coordinates.

A 6-UPS Stewart platform's C_s (18 x 18) is an arrow: closure k's three rows involve its leg's two own
coordinates (the universal joint: A_k, 3 x 2) and the platform's six (B_k, 3 x 6), and no other leg's. numpy's
stacked LAPACK costs a few microseconds per 18 x 18 matrix, mostly per-matrix overhead (docs/speed.md,
"Closed chains"), so the block structure is eliminated here with whole-array numpy and one 6 x 6 solve:

- square system C_s z = r: n_k = a1 x a2 is orthogonal to A_k's columns, so n_k^T B_k y = n_k^T r_k gives the
  shared coordinates y (S = [n_k^T B_k], k x k), then x_k = P_k (r_k - B_k y) with P_k the first two rows of
  [a1 a2 n_k]^-1: (a2 x n_k, n_k x a1) / |n_k|^2, a left inverse of A_k;
- damped step (C_s^T C_s + mu I) z = C_s^T r: the normal matrix is an arrow too (2 x 2 diagonal blocks
  A_k^T A_k + mu I): the Schur complement on the shared coordinates, one k x k solve.

Exact eliminations, no normal equations for the square system: the results agree with the dense LU to rounding
(eps times the condition number). `PointArrow.from_groups` returns None for any other structure (the caller
keeps the dense path).
"""
from __future__ import annotations

import numpy as np

from robocal.model.lie_arrays import cross

OWN = 2          # solved coordinates each point closure owns (a universal joint's two)


class PointArrow:
    """Index maps of the arrow: rows (k, 3) of each closure, own (k, 2) its own solved coordinates, shared (k,)
    the coordinates every other column of its rows may hold (ns = 3 k)."""

    def __init__(self, rows: np.ndarray, own: np.ndarray, shared: np.ndarray):
        self.rows, self.own, self.shared = rows, own, shared
        self.k = len(rows)
        self.columns = np.hstack([own, np.tile(shared, (len(rows), 1))])      # (k, 2 + s): own, then shared

    @classmethod
    def from_groups(cls, groups, n_rows: int, n_solved: int) -> "PointArrow | None":
        """The arrow of the closure groups when they are all point closures (3 rows) each moving exactly two
        coordinates no other closure moves, the remaining ones as many as the closures; else None."""
        if not groups or any(g.kind != "point" for g in groups):
            return None
        rows = np.concatenate([g.rows.reshape(-1, 3) for g in groups])
        # C_s's block of closure k is (E W) (mask2 - mask1): exactly zero where both anchors or neither move
        used = np.concatenate([(g.masks[1] - g.masks[0])[:, 0] != 0.0 for g in groups])     # (k, n_solved)
        k = len(rows)
        count = used.sum(axis=0)
        if 3 * k != n_rows or n_rows != n_solved or (count == 0).any():
            return None
        own_mask = used & (count == 1)
        if not (own_mask.sum(axis=1) == OWN).all():
            return None
        shared = np.flatnonzero(count > 1)
        if len(shared) != k:
            return None
        own = np.array([np.flatnonzero(m) for m in own_mask])
        return cls(rows, own, shared)

    def blocks(self, Cs: np.ndarray, c: np.ndarray | None = None) -> np.ndarray:
        """[A | B] (n, k, 3, 2 + s) of C_s (n, m, ns): closure k's rows on its own and on the shared coordinates;
        with c (n, m), followed by the column c_k (n, k, 3, 3 + s): one matrix product then gives both the
        coupling and the right-hand side."""
        if c is None:
            return Cs[:, self.rows[:, :, None], self.columns[:, None, :]]
        out = np.empty((len(Cs), self.k, 3, self.columns.shape[1] + 1))
        out[..., :-1] = Cs[:, self.rows[:, :, None], self.columns[:, None, :]]
        out[..., -1] = c[:, self.rows]
        return out

    def _square_parts(self, A: np.ndarray):
        """The normals n_k = a1 x a2 (n, k, 3) and P (n, k, 2, 3), the left inverses of A (n, k, 3, 2)."""
        a1, a2 = A[..., 0], A[..., 1]
        normal = cross(a1, a2)
        size = np.einsum("nki,nki->nk", normal, normal)[..., None, None]
        P = np.stack([cross(a2, normal), cross(normal, a1)], axis=2)
        P /= size
        return normal, P

    def _assemble(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """z (n, ns, ...) from the own coordinates x (n, 2 k, ...) and the shared ones y (n, s, ...)."""
        z = np.empty((len(x), 3 * self.k) + x.shape[2:])
        z[:, self.own.ravel()] = x
        z[:, self.shared] = y
        return z

    def newton_step(self, Cs: np.ndarray, c: np.ndarray) -> np.ndarray:
        """-C_s^-1 c (n, ns); raises numpy's LinAlgError where S is singular."""
        AB = self.blocks(Cs, c)
        A, Bc = AB[..., :OWN], AB[..., OWN:]
        normal, P = self._square_parts(A)
        s = self.k
        St = (normal[..., None, :] @ Bc)[..., 0, :]                 # (n, k, s + 1): [S | n_k^T c_k]
        y = np.linalg.solve(St[..., :s], -St[..., s:])              # (n, s, 1)
        x = P @ (Bc[..., s:] + Bc[..., :s] @ y[:, None])            # -P_k (c_k + B_k y): sign folded below
        return self._assemble(-x.reshape(len(x), 2 * s), y[..., 0])

    def damped_step(self, Cs: np.ndarray, c: np.ndarray, mu: np.ndarray) -> np.ndarray:
        """-(C_s^T C_s + mu I)^-1 C_s^T c (n, ns) through the Schur complement on the shared coordinates."""
        AB = self.blocks(Cs, c)
        n, s = len(Cs), self.k
        Bc = AB[..., OWN:]
        products = np.swapaxes(AB[..., :OWN], -1, -2) @ AB        # (n, k, 2, 2 + s + 1): A^T [A | B | c]
        M = products[..., :OWN]                                     # A^T A (n, k, 2, 2) + mu I, inverted in closed form
        M[..., 0, 0] += mu[:, None]
        M[..., 1, 1] += mu[:, None]
        det = M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] * M[..., 1, 0]
        Minv = np.empty_like(M)
        Minv[..., 0, 0], Minv[..., 1, 1] = M[..., 1, 1], M[..., 0, 0]
        Minv[..., 0, 1], Minv[..., 1, 0] = -M[..., 0, 1], -M[..., 1, 0]
        Minv /= det[..., None, None]
        coupling = products[..., OWN:]                              # (n, k, 2, s + 1): [A^T B | A^T c]
        solved = Minv @ coupling
        Bf, Cf = Bc.reshape(n, 3 * s, s + 1), np.ascontiguousarray(coupling).reshape(n, 2 * s, s + 1)
        T = np.swapaxes(Bf, 1, 2) @ Bf - np.swapaxes(Cf, 1, 2) @ solved.reshape(n, 2 * s, s + 1)
        S = T[:, :s, :s]
        S[:, np.arange(s), np.arange(s)] += mu[:, None]
        y = np.linalg.solve(S, T[:, :s, s:])                        # (n, s, 1)
        x = solved[..., s:] - solved[..., :s] @ y[:, None]          # (n, k, 2, 1)
        return -self._assemble(x.reshape(n, 2 * s), y[..., 0])

    def inverse(self, Cs: np.ndarray) -> np.ndarray:
        """C_s^-1 (n, ns, m); raises numpy's LinAlgError where S is singular.
        Shared rows H = S^-1 N (N: n_k^T on closure k's rows), own rows of closure k P_k (E_k - B_k H)."""
        AB = self.blocks(Cs)
        A, B = AB[..., :OWN], AB[..., OWN:]
        normal, P = self._square_parts(A)
        n, k, m = len(Cs), self.k, 3 * self.k
        S = (normal[..., None, :] @ B)[..., 0, :]
        H = np.empty((n, k, m))
        H[:, :, self.rows] = np.linalg.inv(S)[..., None] * normal[:, None]       # (n, s, k, 3) on rows
        X = -((P @ B).reshape(n, 2 * k, k) @ H).reshape(n, k, 2, m)
        X[:, np.arange(k)[:, None], :, self.rows] += P.transpose(1, 3, 0, 2)
        return self._assemble(X.reshape(n, 2 * k, m), H)
