"""Optional numba kernels of the batched closed-chain pass's implicit-function products (robocal.model.
closed_chain_batch): a frame's solved-joint columns J_solved C_s^-1 C_theta, and the first-order moves of the warm
starts -C_s^-1 C_theta dtheta. C_theta (m x nc) holds a few nonzeros per row (a closure sees its own leg's
parameters): the kernels keep only the entries that can be nonzero (robocal.model.closed_chain_compiled's
pattern), and multiply those. Plain Python until `compile_kernels` jits them
(numba imported there only, cache=True); see robocal.model.closure_kernels.
"""
from __future__ import annotations

import numpy as np

from robocal.model.kernel_jit import jit_in_place


def frame_solved_columns(R0, p0, W, moving, solver, C_theta, entry_row, entry_col, ccols, J):
    """J[s, :, ccols] = -Ad(M^-1) W[:, moving] solver[moving] C_theta at each sample s, M = (R0, p0) the frame's
    placement: its LOCAL Jacobian's part through the solved coordinates (dq_s/dtheta = -C_s^-1 C_theta). C_theta
    (n, nnz): its entries that can be nonzero, at rows entry_row and columns entry_col (among ccols)."""
    n, nm, m, nc = R0.shape[0], moving.shape[0], solver.shape[2], ccols.shape[0]
    Z, Y, acc = np.empty((6, nm)), np.empty((6, m)), np.empty((6, nc))
    for s in range(n):
        for k in range(nm):     # Ad(M^-1) [v; w] = [R^T (v - p x w); R^T w]
            col = moving[k]
            v0, v1, v2 = W[s, 0, col], W[s, 1, col], W[s, 2, col]
            w0, w1, w2 = W[s, 3, col], W[s, 4, col], W[s, 5, col]
            x, y, z = p0[s, 0], p0[s, 1], p0[s, 2]
            u0, u1, u2 = v0 - (y * w2 - z * w1), v1 - (z * w0 - x * w2), v2 - (x * w1 - y * w0)
            for a in range(3):
                Z[a, k] = R0[s, 0, a] * u0 + R0[s, 1, a] * u1 + R0[s, 2, a] * u2
                Z[3 + a, k] = R0[s, 0, a] * w0 + R0[s, 1, a] * w1 + R0[s, 2, a] * w2
        for a in range(6):
            for r in range(m):
                Y[a, r] = 0.0
            for k in range(nm):
                zk = Z[a, k]
                for r in range(m):
                    Y[a, r] += zk * solver[s, moving[k], r]
            for col in range(nc):
                acc[a, col] = 0.0
        for e in range(entry_row.shape[0]):
            r, col, value = entry_row[e], entry_col[e], C_theta[s, e]
            for a in range(6):
                acc[a, col] += Y[a, r] * value
        for a in range(6):
            for col in range(nc):
                J[s, a, ccols[col]] = -acc[a, col]


def predicted_moves(solver, C_theta, entry_row, entry_col, dx, dq, dc_max):
    """dq = -solver (C_theta dx) (n, ns) and dc_max = max |C_theta dx| per sample (the closures' first-order change);
    C_theta (n, nnz) as in `frame_solved_columns`."""
    n, ns, m = solver.shape[0], solver.shape[1], solver.shape[2]
    dc = np.empty(m)
    for s in range(n):
        for r in range(m):
            dc[r] = 0.0
        for e in range(entry_row.shape[0]):
            dc[entry_row[e]] += C_theta[s, e] * dx[entry_col[e]]
        top = 0.0
        for r in range(m):
            top = max(top, abs(dc[r]))
        dc_max[s] = top
        for i in range(ns):
            acc = 0.0
            for r in range(m):
                acc += solver[s, i, r] * dc[r]
            dq[s, i] = -acc


KERNELS = ("frame_solved_columns", "predicted_moves")


def compile_kernels():
    """jit the kernels in place (robocal.model.kernel_jit). Raises ImportError without numba."""
    jit_in_place(globals(), KERNELS)
