"""Optional numba kernels of the batched closed-chain pass: one loop over the samples, the per-sample work inside.

numpy's stacked products cost per small matrix, not per flop (docs/speed.md, "Closed chains"), so the batched
pass (robocal.model.closed_chain_batch) spends most of its time in call overhead. These kernels do the same
arithmetic sample by sample in compiled loops, each on any robot the batched path accepts:

- `tree_state`: the tree walk (robocal.model.tree_arrays: revolute, continuous, prismatic, free-flyer,
  spherical joints) and the solved coordinates' world motion columns W; `integrate`: q (+) v;
- `point_rows`: the point closures' rows c and C_s (robocal.model.closure_groups' point branch);
- `active_twists`: the active joints' world twists per parameter column (robocal.model.tree_twists);
- `point_parameter_rows`: the point closures' C_theta (closure_groups.parameter_rows' point branch);
- the 6-UPS block eliminations of robocal.model.point_closure_solve are in robocal.model.arrow_kernels.

The functions stay plain Python until `compile_kernels` jits them in place (numba is imported there only, on
the first batched closed-chain pass: `robocal --version` and open-chain commands never import it). cache=True
keeps the machine code in __pycache__ for later processes.
"""
from __future__ import annotations

import math

import numpy as np

from robocal.model.kernel_jit import jit_in_place

REVOLUTE, CONTINUOUS, PRISMATIC, FREE, SPHERICAL = 0, 1, 2, 3, 4
KIND_CODES = {"revolute": REVOLUTE, "continuous": CONTINUOUS, "prismatic": PRISMATIC, "free": FREE,
              "spherical": SPHERICAL}


def quaternion_matrix(q, s, i, out):
    """Rotation of the unit quaternion q[s, i:i+4] (x y z w), as lie_arrays.quaternion_matrices. (The helpers take
    whole arrays and indices: a view passed to a numba function costs reference counting, more than the
    arithmetic here.)"""
    x, y, z, w = q[s, i], q[s, i + 1], q[s, i + 2], q[s, i + 3]
    out[0, 0], out[0, 1], out[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    out[1, 0], out[1, 1], out[1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    out[2, 0], out[2, 1], out[2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)


def tree_state(q, parents, kinds, idx_q, axis, aligned, unrotated, placement_R, placement_p, col_owner, col_turning,
               col_dir, R, p, W):
    """World placements R (n, nj, 3, 3), p (n, nj, 3) of every joint at q (n, nq), and W (n, 6, ns): the world
    twist [v; w] of each solved coordinate (its owner's rotation times its local direction col_dir; a
    turning coordinate rotates about the owner's origin). aligned[j]: the coordinate axis a revolute or
    continuous joint turns about (-1: another axis); unrotated[j]: its placement's rotation is the identity."""
    n, nj, ns = q.shape[0], parents.shape[0], col_owner.shape[0]
    aR, Rj = np.empty((3, 3)), np.empty((3, 3))
    ap = np.empty(3)
    for s in range(n):
        for a in range(3):
            p[s, 0, a] = 0.0
            for b in range(3):
                R[s, 0, a, b] = 1.0 if a == b else 0.0
        for j in range(1, nj):
            par = parents[j]
            for a in range(3):      # oMi[parent] jointPlacement
                ap[a] = p[s, par, a]
                for b in range(3):
                    ap[a] += R[s, par, a, b] * placement_p[j, b]
                    if unrotated[j]:
                        aR[a, b] = R[s, par, a, b]
                    else:
                        aR[a, b] = (R[s, par, a, 0] * placement_R[j, 0, b] + R[s, par, a, 1] * placement_R[j, 1, b]
                                    + R[s, par, a, 2] * placement_R[j, 2, b])
            kind, iq = kinds[j], idx_q[j]
            if kind == REVOLUTE or kind == CONTINUOUS:
                if kind == REVOLUTE:
                    co, si = math.cos(q[s, iq]), math.sin(q[s, iq])
                else:
                    co, si = q[s, iq], q[s, iq + 1]
                if aligned[j] >= 0:     # about a coordinate axis: two columns of aR turn into each other
                    x = aligned[j]
                    i, k = (x + 1) % 3, (x + 2) % 3
                    for a in range(3):
                        R[s, j, a, i] = co * aR[a, i] + si * aR[a, k]
                        R[s, j, a, k] = co * aR[a, k] - si * aR[a, i]
                        R[s, j, a, x] = aR[a, x]
                        p[s, j, a] = ap[a]
                    continue
                x, y, z = axis[j, 0], axis[j, 1], axis[j, 2]
                t = 1.0 - co      # Rodrigues: I + s [a]x + (1 - c) [a]x^2
                Rj[0, 0], Rj[0, 1], Rj[0, 2] = 1.0 - t * (y * y + z * z), -si * z + t * x * y, si * y + t * x * z
                Rj[1, 0], Rj[1, 1], Rj[1, 2] = si * z + t * x * y, 1.0 - t * (x * x + z * z), -si * x + t * y * z
                Rj[2, 0], Rj[2, 1], Rj[2, 2] = -si * y + t * x * z, si * x + t * y * z, 1.0 - t * (x * x + y * y)
            elif kind == FREE:
                quaternion_matrix(q, s, iq + 3, Rj)
            elif kind == SPHERICAL:
                quaternion_matrix(q, s, iq, Rj)
            else:
                for a in range(3):
                    for b in range(3):
                        Rj[a, b] = 1.0 if a == b else 0.0
            for a in range(3):
                for b in range(3):
                    R[s, j, a, b] = aR[a, 0] * Rj[0, b] + aR[a, 1] * Rj[1, b] + aR[a, 2] * Rj[2, b]
                p[s, j, a] = ap[a]
                if kind == PRISMATIC:
                    p[s, j, a] += q[s, iq] * (aR[a, 0] * axis[j, 0] + aR[a, 1] * axis[j, 1] + aR[a, 2] * axis[j, 2])
                elif kind == FREE:
                    p[s, j, a] += aR[a, 0] * q[s, iq] + aR[a, 1] * q[s, iq + 1] + aR[a, 2] * q[s, iq + 2]
        for k in range(ns):
            W[s, 0, k], W[s, 1, k], W[s, 2, k], W[s, 3, k], W[s, 4, k], W[s, 5, k] = motion_column(
                R, p, s, col_owner[k], col_turning[k], col_dir, k)


def integrate(q, v, kinds, idx_q, idx_v, small_angle, out):
    """out = q (+) v (n, nq) for the stack, as tree_arrays.TreeArrays.integrate (Pinocchio's integrate, v LOCAL):
    one-dof joints add, a continuous joint turns its (cos, sin), a free-flyer moves by exp6 and a spherical
    joint by exp3 (Taylor coefficients below small_angle)."""
    n, nj = q.shape[0], kinds.shape[0]
    Rq = np.empty((3, 3))
    for s in range(n):
        for i in range(q.shape[1]):
            out[s, i] = q[s, i]
        for j in range(1, nj):
            kind, iq, iv = kinds[j], idx_q[j], idx_v[j]
            if kind == REVOLUTE or kind == PRISMATIC:
                out[s, iq] = q[s, iq] + v[s, iv]
            elif kind == CONTINUOUS:
                co, si = math.cos(v[s, iv]), math.sin(v[s, iv])
                out[s, iq] = q[s, iq] * co - q[s, iq + 1] * si
                out[s, iq + 1] = q[s, iq + 1] * co + q[s, iq] * si
            else:
                iw, iquat = (iv + 3, iq + 3) if kind == FREE else (iv, iq)
                w0, w1, w2 = v[s, iw], v[s, iw + 1], v[s, iw + 2]
                theta = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
                if kind == FREE:        # translation R V(w) v_lin
                    x0, x1, x2 = v[s, iv], v[s, iv + 1], v[s, iv + 2]
                    if theta < small_angle:
                        a, b = 0.5 - theta ** 2 / 24.0, 1.0 / 6.0 - theta ** 2 / 120.0
                    else:
                        a = (1.0 - math.cos(theta)) / (theta * theta)
                        b = (theta - math.sin(theta)) / (theta * theta * theta)
                    c0, c1, c2 = w1 * x2 - w2 * x1, w2 * x0 - w0 * x2, w0 * x1 - w1 * x0
                    d0, d1, d2 = w1 * c2 - w2 * c1, w2 * c0 - w0 * c2, w0 * c1 - w1 * c0
                    t0, t1, t2 = x0 + a * c0 + b * d0, x1 + a * c1 + b * d1, x2 + a * c2 + b * d2
                    quaternion_matrix(q, s, iquat, Rq)
                    for r in range(3):
                        out[s, iq + r] = q[s, iq + r] + (Rq[r, 0] * t0 + Rq[r, 1] * t1 + Rq[r, 2] * t2)
                k = 0.5 - theta ** 2 / 48.0 if theta < small_angle else math.sin(0.5 * theta) / theta
                b0, b1, b2, b3 = k * w0, k * w1, k * w2, math.cos(0.5 * theta)
                a0, a1, a2, a3 = q[s, iquat], q[s, iquat + 1], q[s, iquat + 2], q[s, iquat + 3]
                e0 = a3 * b0 + a0 * b3 + a1 * b2 - a2 * b1
                e1 = a3 * b1 - a0 * b2 + a1 * b3 + a2 * b0
                e2 = a3 * b2 + a0 * b1 - a1 * b0 + a2 * b3
                e3 = a3 * b3 - a0 * b0 - a1 * b1 - a2 * b2
                norm = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)
                out[s, iquat], out[s, iquat + 1] = e0 / norm, e1 / norm
                out[s, iquat + 2], out[s, iquat + 3] = e2 / norm, e3 / norm


def motion_column(R, p, s, j, turning, direction, k):
    """(v, w) as six floats: the world twist of a coordinate of joint j at sample s moving along (turning: about)
    its local direction[k]."""
    d0 = R[s, j, 0, 0] * direction[k, 0] + R[s, j, 0, 1] * direction[k, 1] + R[s, j, 0, 2] * direction[k, 2]
    d1 = R[s, j, 1, 0] * direction[k, 0] + R[s, j, 1, 1] * direction[k, 1] + R[s, j, 1, 2] * direction[k, 2]
    d2 = R[s, j, 2, 0] * direction[k, 0] + R[s, j, 2, 1] * direction[k, 1] + R[s, j, 2, 2] * direction[k, 2]
    if turning:
        return (p[s, j, 1] * d2 - p[s, j, 2] * d1, p[s, j, 2] * d0 - p[s, j, 0] * d2, p[s, j, 0] * d1 - p[s, j, 1] * d0,
                d0, d1, d2)
    return d0, d1, d2, 0.0, 0.0, 0.0


def anchor(R, p, s, j, fR, fp, unrotated, k, Ra, pa, o):
    """World pose (Ra[o], pa[o]) of anchor k on joint j at sample s: oMi[j] times its placement (fR[k], fp[k]);
    unrotated[k]: fR[k] is the identity (no product)."""
    for a in range(3):
        pa[o, a] = p[s, j, a] + R[s, j, a, 0] * fp[k, 0] + R[s, j, a, 1] * fp[k, 1] + R[s, j, a, 2] * fp[k, 2]
        if unrotated[k]:
            for b in range(3):
                Ra[o, a, b] = R[s, j, a, b]
        else:
            for b in range(3):
                Ra[o, a, b] = R[s, j, a, 0] * fR[k, 0, b] + R[s, j, a, 1] * fR[k, 1, b] + R[s, j, a, 2] * fR[k, 2, b]


def point_rows(R, p, W, joints1, joints2, R1f, p1f, R2f, p2f, unrotated1, unrotated2, rows, mask_cols, mask_values, c, Cs):
    """c = R1^T (p2 - p1) and C_s = [R1^T, p2 x rows of R1^T] W on the solved columns that move the closure
    (mask_cols (k, w), padded with -1, with their signs mask_values; as closure_groups.closure_state), written
    into the rows (k, 3) of c (n, m) and Cs (n, m, ns). Cs must be zero on entry: only the moving columns are
    written (zeroing the others here took half the kernel's time; the caller's np.zeros is nearly free)."""
    n, k_count = R.shape[0], joints1.shape[0]
    R1, R2 = np.empty((1, 3, 3)), np.empty((1, 3, 3))
    p1, p2 = np.empty((1, 3)), np.empty((1, 3))
    e, f = np.empty((3, 3)), np.empty((3, 3))
    for s in range(n):
        for k in range(k_count):
            anchor(R, p, s, joints1[k], R1f, p1f, unrotated1, k, R1, p1, 0)
            anchor(R, p, s, joints2[k], R2f, p2f, unrotated2, k, R2, p2, 0)
            x0, x1, x2 = p2[0, 0], p2[0, 1], p2[0, 2]
            for i in range(3):
                r = rows[k, i]
                e0, e1, e2 = R1[0, 0, i], R1[0, 1, i], R1[0, 2, i]        # row i of R1^T
                c[s, r] = e0 * (x0 - p1[0, 0]) + e1 * (x1 - p1[0, 1]) + e2 * (x2 - p1[0, 2])
                e[i, 0], e[i, 1], e[i, 2] = e0, e1, e2
                f[i, 0], f[i, 1], f[i, 2] = x1 * e2 - x2 * e1, x2 * e0 - x0 * e2, x0 * e1 - x1 * e0
            for t in range(mask_cols.shape[1]):       # each moving column's twist read once for the three rows
                col = mask_cols[k, t]
                if col < 0:
                    break
                m = mask_values[k, t]
                v0, v1, v2 = W[s, 0, col], W[s, 1, col], W[s, 2, col]
                w0, w1, w2 = W[s, 3, col], W[s, 4, col], W[s, 5, col]
                for i in range(3):
                    Cs[s, rows[k, i], col] = m * (e[i, 0] * v0 + e[i, 1] * v1 + e[i, 2] * v2
                                                  + f[i, 0] * w0 + f[i, 1] * w1 + f[i, 2] * w2)


def active_twists(R, p, active, placed, parents, placement_R, placement_p, blocks, offset_owner, offset_active,
                  offset_turning, offset_dir, offset_rows, G):
    """G (n, a, 6, c): world twist of each active joint per own parameter column (tree_twists.TreeTwists.twists):
    Ad(oMi[parent] jointPlacement) blocks[a] for those with placement parameters, plus each offset's motion
    column times its row."""
    n, n_active, width = R.shape[0], active.shape[0], blocks.shape[2]
    aR, ap = np.empty((3, 3)), np.empty(3)
    for s in range(n):
        for a in range(n_active):
            if not placed[a]:
                for r in range(6):
                    for col in range(width):
                        G[s, a, r, col] = 0.0
                continue
            j = active[a]
            par = parents[j]
            for x in range(3):
                ap[x] = p[s, par, x]
                for y in range(3):
                    ap[x] += R[s, par, x, y] * placement_p[j, y]
                    aR[x, y] = (R[s, par, x, 0] * placement_R[j, 0, y] + R[s, par, x, 1] * placement_R[j, 1, y]
                                + R[s, par, x, 2] * placement_R[j, 2, y])
            for col in range(width):
                # [v; w] = [aR bv + ap x (aR bw); aR bw]
                bv0, bv1, bv2 = blocks[a, 0, col], blocks[a, 1, col], blocks[a, 2, col]
                bw0, bw1, bw2 = blocks[a, 3, col], blocks[a, 4, col], blocks[a, 5, col]
                w0 = aR[0, 0] * bw0 + aR[0, 1] * bw1 + aR[0, 2] * bw2
                w1 = aR[1, 0] * bw0 + aR[1, 1] * bw1 + aR[1, 2] * bw2
                w2 = aR[2, 0] * bw0 + aR[2, 1] * bw1 + aR[2, 2] * bw2
                G[s, a, 0, col] = aR[0, 0] * bv0 + aR[0, 1] * bv1 + aR[0, 2] * bv2 + ap[1] * w2 - ap[2] * w1
                G[s, a, 1, col] = aR[1, 0] * bv0 + aR[1, 1] * bv1 + aR[1, 2] * bv2 + ap[2] * w0 - ap[0] * w2
                G[s, a, 2, col] = aR[2, 0] * bv0 + aR[2, 1] * bv1 + aR[2, 2] * bv2 + ap[0] * w1 - ap[1] * w0
                G[s, a, 3, col], G[s, a, 4, col], G[s, a, 5, col] = w0, w1, w2
        for t in range(offset_owner.shape[0]):
            twist = motion_column(R, p, s, offset_owner[t], offset_turning[t], offset_dir, t)
            a = offset_active[t]
            for col in range(width):
                for r in range(6):
                    G[s, a, r, col] += twist[r] * offset_rows[t, col]


def point_parameter_rows(R, p, G, joints1, joints2, R1f, p1f, R2f, p2f, unrotated1, unrotated2, pair_side, pair_k, pair_a, pair_entry,
                         frame_side, frame_k, frame_entry, F, out):
    """Adds the point closures' C_theta into out (n, nnz), its entries that can be nonzero (closure_groups.
    parameter_rows, point branch): a pair (anchor k of side 0 or 1, active joint a supporting it) adds
    -+ R1^T (Uv + Uw x p2) of U = G[a] column by column; an anchor frame's own placement columns (LOCAL twists F
    (rows, 6, f)) add cp x Fw - Fv (side 0, cp = c_k) or R1^T R2 Fv (side 1). pair_entry (P, 3, c) and
    frame_entry (T, 3, f): the entry of out that row i of the closure and that column go to (-1: padding)."""
    n, width = R.shape[0], pair_entry.shape[2]
    k_count = joints1.shape[0]
    R1, R2 = np.empty((k_count, 3, 3)), np.empty((k_count, 3, 3))
    p1, p2, cp, R12 = np.empty((k_count, 3)), np.empty((k_count, 3)), np.empty(3), np.empty((3, 3))
    for s in range(n):
        for k in range(k_count):
            anchor(R, p, s, joints1[k], R1f, p1f, unrotated1, k, R1, p1, k)
            anchor(R, p, s, joints2[k], R2f, p2f, unrotated2, k, R2, p2, k)
        for t in range(pair_k.shape[0]):
            k, a = pair_k[t], pair_a[t]
            sign = 1.0 if pair_side[t] else -1.0
            for col in range(width):
                if pair_entry[t, 0, col] < 0:
                    continue
                v0 = G[s, a, 0, col] + G[s, a, 4, col] * p2[k, 2] - G[s, a, 5, col] * p2[k, 1]
                v1 = G[s, a, 1, col] + G[s, a, 5, col] * p2[k, 0] - G[s, a, 3, col] * p2[k, 2]
                v2 = G[s, a, 2, col] + G[s, a, 3, col] * p2[k, 1] - G[s, a, 4, col] * p2[k, 0]
                for i in range(3):
                    out[s, pair_entry[t, i, col]] += sign * (R1[k, 0, i] * v0 + R1[k, 1, i] * v1 + R1[k, 2, i] * v2)
        for t in range(frame_k.shape[0]):
            k = frame_k[t]
            if frame_side[t]:      # R1^T R2, once per anchor frame
                for i in range(3):
                    for b in range(3):
                        R12[i, b] = R1[k, 0, i] * R2[k, 0, b] + R1[k, 1, i] * R2[k, 1, b] + R1[k, 2, i] * R2[k, 2, b]
            for b in range(3):     # side 0: cp = c_k = R1^T (p2 - p1)
                cp[b] = (R1[k, 0, b] * (p2[k, 0] - p1[k, 0]) + R1[k, 1, b] * (p2[k, 1] - p1[k, 1])
                         + R1[k, 2, b] * (p2[k, 2] - p1[k, 2]))
            for col in range(frame_entry.shape[2]):
                if frame_entry[t, 0, col] < 0:
                    continue
                for i in range(3):
                    if frame_side[t]:      # R1^T R2 Fv
                        acc = R12[i, 0] * F[t, 0, col] + R12[i, 1] * F[t, 1, col] + R12[i, 2] * F[t, 2, col]
                    else:                   # cp x Fw - Fv
                        i1, i2 = (i + 1) % 3, (i + 2) % 3
                        acc = cp[i1] * F[t, 3 + i2, col] - cp[i2] * F[t, 3 + i1, col] - F[t, i, col]
                    out[s, frame_entry[t, i, col]] += acc


KERNELS = ("quaternion_matrix", "motion_column", "anchor", "tree_state", "integrate", "point_rows", "active_twists",
           "point_parameter_rows")


def compile_kernels():
    """jit the kernels in place (robocal.model.kernel_jit). Raises ImportError without numba."""
    jit_in_place(globals(), KERNELS)
