"""Optional numba kernels of the 6-UPS block eliminations (robocal.model.point_closure_solve), one loop over the
samples with the per-sample elimination inside (see robocal.model.closure_kernels for why).

Same formulas as PointArrow's newton_step, damped_step and inverse; the shared k x k block is solved by Gaussian
elimination with partial pivoting (`solve_small`). A zero pivot (where numpy's solve raises LinAlgError) or a
singular 2 x 2 block leaves NaN in that sample's result, and the caller takes the dense path for the block, as
the numpy path does. Plain Python until `compile_kernels` jits them (numba imported there only, cache=True).
"""
from __future__ import annotations

import math

import numpy as np

from robocal.model.kernel_jit import jit_in_place


def solve_small(S, b, x):
    """x = S^-1 b for one small square S (Gaussian elimination with partial pivoting, S and b overwritten);
    False (x untouched) on a zero pivot, where numpy's solve raises LinAlgError."""
    m = S.shape[0]
    for col in range(m):
        best, at = abs(S[col, col]), col
        for r in range(col + 1, m):
            if abs(S[r, col]) > best:
                best, at = abs(S[r, col]), r
        if best == 0.0:
            return False
        if at != col:
            for c2 in range(m):
                S[col, c2], S[at, c2] = S[at, c2], S[col, c2]
            for c2 in range(b.shape[1]):
                b[col, c2], b[at, c2] = b[at, c2], b[col, c2]
        for r in range(col + 1, m):
            f = S[r, col] / S[col, col]
            if f != 0.0:
                for c2 in range(col + 1, m):
                    S[r, c2] -= f * S[col, c2]
                for c2 in range(b.shape[1]):
                    b[r, c2] -= f * b[col, c2]
    for c2 in range(b.shape[1]):
        for r in range(m - 1, -1, -1):
            acc = b[r, c2]
            for c3 in range(r + 1, m):
                acc -= S[r, c3] * x[c3, c2]
            x[r, c2] = acc / S[r, r]
    return True


def arrow_parts(Cs, s, rows, own, normal, P):
    """Closure k's normal n_k = a1 x a2 and the left inverse P_k (2, 3) of its own columns A_k = [a1 a2]."""
    for k in range(rows.shape[0]):
        a1 = (Cs[s, rows[k, 0], own[k, 0]], Cs[s, rows[k, 1], own[k, 0]], Cs[s, rows[k, 2], own[k, 0]])
        a2 = (Cs[s, rows[k, 0], own[k, 1]], Cs[s, rows[k, 1], own[k, 1]], Cs[s, rows[k, 2], own[k, 1]])
        n0, n1, n2 = a1[1] * a2[2] - a1[2] * a2[1], a1[2] * a2[0] - a1[0] * a2[2], a1[0] * a2[1] - a1[1] * a2[0]
        size = n0 * n0 + n1 * n1 + n2 * n2
        normal[k, 0], normal[k, 1], normal[k, 2] = n0, n1, n2
        P[k, 0, 0], P[k, 0, 1], P[k, 0, 2] = ((a2[1] * n2 - a2[2] * n1) / size, (a2[2] * n0 - a2[0] * n2) / size,
                                              (a2[0] * n1 - a2[1] * n0) / size)
        P[k, 1, 0], P[k, 1, 1], P[k, 1, 2] = ((n1 * a1[2] - n2 * a1[1]) / size, (n2 * a1[0] - n0 * a1[2]) / size,
                                              (n0 * a1[1] - n1 * a1[0]) / size)


def arrow_newton(Cs, c, rows, own, shared, z):
    """z = -C_s^-1 c (point_closure_solve.PointArrow.newton_step); NaN where the shared block is singular."""
    n, k_count, ns = Cs.shape[0], rows.shape[0], shared.shape[0]
    normal, P = np.empty((k_count, 3)), np.empty((k_count, 2, 3))
    S, rhs, y = np.empty((k_count, ns)), np.empty((k_count, 1)), np.empty((ns, 1))
    for s in range(n):
        arrow_parts(Cs, s, rows, own, normal, P)
        for k in range(k_count):
            rhs[k, 0] = 0.0
            for i in range(3):
                rhs[k, 0] -= normal[k, i] * c[s, rows[k, i]]
            for j in range(ns):
                S[k, j] = (normal[k, 0] * Cs[s, rows[k, 0], shared[j]] + normal[k, 1] * Cs[s, rows[k, 1], shared[j]]
                           + normal[k, 2] * Cs[s, rows[k, 2], shared[j]])
        if not solve_small(S, rhs, y):
            for i in range(z.shape[1]):
                z[s, i] = np.nan
            continue
        for j in range(ns):
            z[s, shared[j]] = y[j, 0]
        for k in range(k_count):
            for a in range(2):
                acc = 0.0
                for i in range(3):
                    r = c[s, rows[k, i]]
                    for j in range(ns):
                        r += Cs[s, rows[k, i], shared[j]] * y[j, 0]
                    acc += P[k, a, i] * r
                z[s, own[k, a]] = -acc


def arrow_damped(Cs, c, mu, rows, own, shared, z):
    """z = -(C_s^T C_s + mu I)^-1 C_s^T c through the Schur complement on the shared coordinates
    (PointArrow.damped_step); NaN where a 2 x 2 block or the complement is singular."""
    n, k_count, ns = Cs.shape[0], rows.shape[0], shared.shape[0]
    AB = np.empty((k_count, 3, 3 + ns))          # per closure [A | B | c]
    solved = np.empty((k_count, 2, ns + 1))      # (A^T A + mu I)^-1 A^T [B | c]
    coupling = np.empty((k_count, 2, ns + 1))
    T, rhs, y = np.empty((ns, ns)), np.empty((ns, 1)), np.empty((ns, 1))
    for s in range(n):
        for k in range(k_count):
            for i in range(3):
                r = rows[k, i]
                AB[k, i, 0], AB[k, i, 1] = Cs[s, r, own[k, 0]], Cs[s, r, own[k, 1]]
                for j in range(ns):
                    AB[k, i, 2 + j] = Cs[s, r, shared[j]]
                AB[k, i, 2 + ns] = c[s, r]
            m00 = AB[k, 0, 0] ** 2 + AB[k, 1, 0] ** 2 + AB[k, 2, 0] ** 2 + mu[s]
            m11 = AB[k, 0, 1] ** 2 + AB[k, 1, 1] ** 2 + AB[k, 2, 1] ** 2 + mu[s]
            m01 = AB[k, 0, 0] * AB[k, 0, 1] + AB[k, 1, 0] * AB[k, 1, 1] + AB[k, 2, 0] * AB[k, 2, 1]
            det = m00 * m11 - m01 * m01
            for j in range(ns + 1):
                c0 = AB[k, 0, 0] * AB[k, 0, 2 + j] + AB[k, 1, 0] * AB[k, 1, 2 + j] + AB[k, 2, 0] * AB[k, 2, 2 + j]
                c1 = AB[k, 0, 1] * AB[k, 0, 2 + j] + AB[k, 1, 1] * AB[k, 1, 2 + j] + AB[k, 2, 1] * AB[k, 2, 2 + j]
                coupling[k, 0, j], coupling[k, 1, j] = c0, c1
                solved[k, 0, j] = (m11 * c0 - m01 * c1) / det
                solved[k, 1, j] = (m00 * c1 - m01 * c0) / det
        for a in range(ns):
            for b in range(ns + 1):
                acc = 0.0
                for k in range(k_count):
                    for i in range(3):
                        acc += AB[k, i, 2 + a] * AB[k, i, 2 + b]
                    acc -= coupling[k, 0, a] * solved[k, 0, b] + coupling[k, 1, a] * solved[k, 1, b]
                if b < ns:
                    T[a, b] = acc + (mu[s] if a == b else 0.0)
                else:
                    rhs[a, 0] = acc
        if not solve_small(T, rhs, y):
            for i in range(z.shape[1]):
                z[s, i] = np.nan
            continue
        for j in range(ns):
            z[s, shared[j]] = -y[j, 0]
        for k in range(k_count):
            for a in range(2):
                acc = solved[k, a, ns]
                for j in range(ns):
                    acc -= solved[k, a, j] * y[j, 0]
                z[s, own[k, a]] = -acc


def arrow_inverse(Cs, rows, own, shared, inv, bound):
    """inv = C_s^-1 (PointArrow.inverse) and bound = 1 / (|C_s|_F |C_s^-1|_F) (<= s_min / s_max); NaN in inv
    where the shared block is singular. Shared rows H = S^-1 N (N: n_k^T on closure k's rows), own rows of
    closure k P_k (E_k - B_k H)."""
    n, k_count, ns, m = Cs.shape[0], rows.shape[0], shared.shape[0], Cs.shape[1]
    normal, P = np.empty((k_count, 3)), np.empty((k_count, 2, 3))
    S, eye, Sinv = np.empty((k_count, ns)), np.empty((ns, ns)), np.empty((ns, ns))
    PB, H, X = np.empty((k_count, 2, ns)), np.empty((ns, m)), np.empty(m)
    for s in range(n):
        arrow_parts(Cs, s, rows, own, normal, P)
        for k in range(k_count):
            for j in range(ns):
                S[k, j] = (normal[k, 0] * Cs[s, rows[k, 0], shared[j]] + normal[k, 1] * Cs[s, rows[k, 1], shared[j]]
                           + normal[k, 2] * Cs[s, rows[k, 2], shared[j]])
                for a in range(2):
                    PB[k, a, j] = (P[k, a, 0] * Cs[s, rows[k, 0], shared[j]] + P[k, a, 1] * Cs[s, rows[k, 1], shared[j]]
                                   + P[k, a, 2] * Cs[s, rows[k, 2], shared[j]])
        for a in range(ns):
            for b in range(ns):
                eye[a, b] = 1.0 if a == b else 0.0
        if not solve_small(S, eye, Sinv):
            for a in range(m):
                for b in range(m):
                    inv[s, a, b] = np.nan
            bound[s] = 0.0
            continue
        for j in range(ns):             # H = S^-1 N, kept whole in H (ns, m) for the own rows' products
            for col in range(m):
                H[j, col] = 0.0
            for k in range(k_count):
                for i in range(3):
                    H[j, rows[k, i]] = Sinv[j, k] * normal[k, i]
            for col in range(m):
                inv[s, shared[j], col] = H[j, col]
        for k in range(k_count):       # X_k = -(P_k B_k) H, plus P_k on the closure's own rows
            for a in range(2):
                for col in range(m):
                    X[col] = 0.0
                for j in range(ns):
                    f = PB[k, a, j]
                    for col in range(m):
                        X[col] -= f * H[j, col]
                for i in range(3):
                    X[rows[k, i]] += P[k, a, i]
                row = own[k, a]
                for col in range(m):
                    inv[s, row, col] = X[col]
        a_norm, i_norm = 0.0, 0.0
        for a in range(m):
            for b in range(Cs.shape[2]):
                a_norm += Cs[s, a, b] ** 2
                i_norm += inv[s, b, a] ** 2
        bound[s] = 1.0 / math.sqrt(a_norm * i_norm)


KERNELS = ("solve_small", "arrow_parts", "arrow_newton", "arrow_damped", "arrow_inverse")


def compile_kernels():
    """jit the kernels in place (robocal.model.kernel_jit). Raises ImportError without numba."""
    jit_in_place(globals(), KERNELS)
