"""The batched closed-chain pass's hot loops through the numba kernels (robocal.model.closure_kernels,
arrow_kernels, sensitivity_kernels), when numba is installed (robocal's optional [fast] extra).

`CompiledPass` holds one pass's tables (the tree's joints, the solved coordinates, the active joints' parameter
blocks, the point closures' anchors and parameter pairs) as flat arrays and offers what ClosedChainBatch needs:
`state` (tree walk, W, c, C_s), `integrate`, `twists_at`, `parameter_rows` (C_theta at its possibly-nonzero
entries), the 6-UPS arrow's steps and inverse, a frame's solved-joint columns and the predicted starts' moves.
What the kernels do not cover stays numpy, from the same inputs: closure kinds other than the point (revolute,
distance, frame rows through closure_groups.group_state / parameter_rows), a C_s without the arrow structure (the
dense LU in ClosedChainBatch), and every breakdown (NaN from a kernel sends the block to the numpy path).

`numba_wanted(use_numba, n)`: None uses numba for a pass of n >= NUMBA_MIN_SAMPLES samples when it imports and the
environment variable ROBOCAL_NO_NUMBA is unset (or 0); False keeps the numpy path; True requires numba (ImportError
without it). The choice depends on the pass only, never on what the process ran before: a fit gives the same
numbers serially and on a cluster's fresh workers.
"""
from __future__ import annotations

import copy

import numpy as np

from robocal.model import arrow_kernels, closure_kernels, sensitivity_kernels
from robocal.model.closure_groups import group_state, parameter_rows
from robocal.model.kernel_jit import numba_chosen
from robocal.model.tree_arrays import SMALL_ANGLE


# Loading numba and the kernels from its cache costs ~0.3 s once per process (docs/speed.md, "Closed chains"); they
# save 11-13 us per sample and pass, ~20 passes a calibration: from ~1000 samples a pass one calibration repays it
NUMBA_MIN_SAMPLES = 1000


def numba_wanted(use_numba: bool | None, n: int | None = None) -> bool:
    """use_numba, or for None: the pass has at least NUMBA_MIN_SAMPLES samples n and robocal.model.kernel_jit's
    numba_chosen says yes (ROBOCAL_NO_NUMBA unset and numba imports; the kernels are jitted here, on the first
    such pass: seconds the first time, then loaded from numba's cache)."""
    if use_numba is None and n is not None and n < NUMBA_MIN_SAMPLES:
        return False
    return numba_chosen(use_numba, compile_all)


def compile_all() -> None:
    closure_kernels.compile_kernels()
    arrow_kernels.compile_kernels()
    sensitivity_kernels.compile_kernels()


def _local_directions(tree, v: np.ndarray):
    """(owner joints, turning flags, local directions (len(v), 3)) of the velocity coordinates v: a one-dof joint's
    axis, a free-flyer's or spherical joint's coordinate axis."""
    v = np.asarray(v, dtype=int)
    owner = tree.v_owner[v]
    direction = np.where((tree.v_kind[v] <= 1)[:, None], tree.axis[owner], np.eye(3)[tree.v_dof[v] % 3])
    return owner.astype(np.int64), tree.v_turning[v].astype(np.bool_), np.ascontiguousarray(direction, dtype=float)


class CompiledPass:
    """One ClosedChainBatch's tables for the kernels. tree: TreeArrays at this pass's placements; groups: its
    closure groups (with_placements); solved: solved velocity coordinates; twists: TreeTwists; group_pairs,
    group_frames, positions, nc: ClosedChainBatch's parameter-row tables; arrow: PointArrow or None."""

    def __init__(self, tree, groups, n_rows, solved, twists, group_pairs, group_frames, positions, nc, arrow):
        self.n_rows, self.ns = n_rows, len(solved)
        self._read_placements(tree, groups)
        self.parents = np.asarray(tree.parent_array, dtype=np.int64)
        self.kinds = np.array([-1] + [closure_kernels.KIND_CODES[k] for k in tree.kinds[1:]], dtype=np.int64)
        self.idx_q = np.asarray(tree.q_array, dtype=np.int64)
        self.idx_v = np.asarray(tree.idx_v, dtype=np.int64)
        self.axis = np.ascontiguousarray(tree.axis, dtype=float)
        one_hot = (np.abs(tree.axis).sum(axis=1) == 1.0) & (tree.axis.max(axis=1) == 1.0)
        self.aligned = np.where(one_hot, np.argmax(tree.axis, axis=1), -1).astype(np.int64)
        self.columns = _local_directions(tree, solved)
        self.twists = twists
        active = twists.active.astype(np.int64)
        placed = np.zeros(len(active), dtype=np.bool_)
        placed[twists.placed] = True
        offsets = _local_directions(tree, twists.offset_v)
        width = twists.blocks.shape[2]
        rows = np.array(twists.offset_rows, dtype=float).reshape(len(twists.offset_v), width)
        self.twist_tables = (active, placed, self.parents, np.ascontiguousarray(twists.blocks, dtype=float), offsets[0],
                             np.array(twists.offset_owner, dtype=np.int64), offsets[1], offsets[2], rows)
        self.points = [self._point_tables(g, pairs, frames, positions, nc) if g.kind == "point" else None
                       for g, pairs, frames in zip(groups, group_pairs, group_frames)]
        self.group_pairs, self.group_frames, self.positions, self.nc = group_pairs, group_frames, positions, nc
        self._pattern()
        self.arrow = None if arrow is None else (arrow.rows.astype(np.int64), arrow.own.astype(np.int64),
                                                 arrow.shared.astype(np.int64))

    def _pattern(self) -> None:
        """The entries of C_theta (m x nc) that can be nonzero, the same at every sample: (entry_row, entry_col), and
        per point group the entry each (pair or anchor frame, row, column) adds to (-1: padding); a group of another
        kind holds all its rows' columns (`dense`). C_theta is kept as (n, nnz) in this path."""
        entries: dict = {}

        def entry_table(cols, rows_of):      # cols (T, c) among nc, padded with nc; rows_of (T, 3)
            out = np.full(cols.shape[:1] + (3,) + cols.shape[1:], -1, dtype=np.int64)
            for t, i, c in np.ndindex(out.shape):
                if cols[t, c] < self.nc:
                    out[t, i, c] = entries.setdefault((int(rows_of[t, i]), int(cols[t, c])), len(entries))
            return out

        self.dense = []
        for g, point in zip(self.groups, self.points):
            if point is None:
                self.dense.append(np.array([entries.setdefault((int(r), c), len(entries)) for r in g.rows
                                            for c in range(self.nc)], dtype=np.int64))
                continue
            rows = point[0][2]
            side, pk, pa, pair_cols = point[2]
            fside, fk, frame_cols, F = point[3]
            point[2] = (side, pk, pa, entry_table(pair_cols, rows[pk]))
            point[3] = (fside, fk, entry_table(frame_cols, rows[fk]), F)
            self.dense.append(None)
        pattern = np.array(list(entries), dtype=np.int64).reshape(-1, 2)
        self.entry_row, self.entry_col = np.ascontiguousarray(pattern[:, 0]), np.ascontiguousarray(pattern[:, 1])

    def _read_placements(self, tree, groups) -> None:
        self.tree, self.groups = tree, groups
        self.placement_R = np.ascontiguousarray(tree.placement_R, dtype=float)
        self.placement_p = np.ascontiguousarray(tree.placement_p, dtype=float)
        self.unrotated = np.asarray(tree.unrotated, dtype=np.bool_)
        # per point group: R1f, p1f, R2f, p2f and whether each anchor rotation is the identity (no product)
        self.anchors = [tuple(np.ascontiguousarray(a, dtype=float) for side in g.placements for a in side)
                        + tuple(np.all(side[0] == np.eye(3), axis=(1, 2)) for side in g.placements)
                        if g.kind == "point" else None for g in groups]

    def at_placements(self, tree, groups) -> "CompiledPass":
        """These tables with another pass's joint and anchor placements (same structure and parameter blocks)."""
        out = copy.copy(self)
        out._read_placements(tree, groups)
        return out

    @staticmethod
    def _point_tables(g, pairs, frames, positions, nc):
        """A point group's anchor joints and rows, its masks, and its parameter pairs and anchor-frame columns,
        flattened over the two sides."""
        anchors = (g.joints[0].astype(np.int64), g.joints[1].astype(np.int64), g.rows.reshape(-1, 3).astype(np.int64))
        signs = (g.masks[1] - g.masks[0])[:, 0]          # (k, ns): +-1 where a coordinate moves the closure
        width = max(int((signs != 0.0).sum(axis=1).max(initial=0)), 1)
        mask_cols, mask_values = np.full((len(signs), width), -1, dtype=np.int64), np.zeros((len(signs), width))
        for k, row in enumerate(signs):
            nonzero = np.flatnonzero(row)
            mask_cols[k, :len(nonzero)], mask_values[k, :len(nonzero)] = nonzero, row[nonzero]
        mask = (mask_cols, mask_values)
        side, pk, pa, cols = [], [], [], []
        for s, (k_index, a_index) in enumerate(pairs):
            side += [s] * len(k_index)
            pk.append(k_index)
            pa.append(a_index)
            cols.append(np.asarray(positions[a_index], dtype=np.int64).reshape(len(a_index), positions.shape[1]))
        width = max([c.shape[1] for c in cols] + [1])
        pair_cols = np.full((sum(len(k) for k in pk), width), nc, dtype=np.int64)
        if len(pair_cols):
            stacked = np.concatenate([np.pad(c, ((0, 0), (0, width - c.shape[1])), constant_values=nc) for c in cols])
            pair_cols[:] = stacked
        pair = (np.array(side, dtype=np.bool_), np.concatenate(pk).astype(np.int64),
                np.concatenate(pa).astype(np.int64), pair_cols)
        fside, fk, fcols, fF = [], [], [], []
        for s, frame in enumerate(frames):
            if frame is not None:
                c, F = frame
                fside += [s] * len(c)
                fk.append(np.arange(len(c)))
                fcols.append(c)
                fF.append(F)
        fwidth = max([c.shape[1] for c in fcols] + [1])
        frame_cols = np.full((len(fside), fwidth), nc, dtype=np.int64)
        F_all = np.zeros((len(fside), 6, fwidth))
        at = 0
        for c, F in zip(fcols, fF):
            frame_cols[at:at + len(c), :c.shape[1]] = c
            F_all[at:at + len(c), :, :F.shape[2]] = F
            at += len(c)
        frame = (np.array(fside, dtype=np.bool_), np.concatenate(fk).astype(np.int64) if fk else
                 np.zeros(0, dtype=np.int64), frame_cols, F_all)
        return [anchors, mask, pair, frame]

    def state(self, q: np.ndarray) -> dict:
        """closure_groups.closure_state at q (n, nq): R, p, W, c, Cs."""
        n, nj = len(q), len(self.parents)
        R, p, W = np.empty((n, nj, 3, 3)), np.empty((n, nj, 3)), np.empty((n, 6, self.ns))
        closure_kernels.tree_state(np.ascontiguousarray(q, dtype=float), self.parents, self.kinds, self.idx_q,
                                   self.axis, self.aligned, self.unrotated, self.placement_R, self.placement_p,
                                   *self.columns, R, p, W)
        c, Cs = np.empty((n, self.n_rows)), np.zeros((n, self.n_rows, self.ns))    # zeros: point_rows' contract
        for g, point, placed in zip(self.groups, self.points, self.anchors):
            if point is not None:
                closure_kernels.point_rows(R, p, W, *point[0][:2], *placed, point[0][2], *point[1], c, Cs)
            else:
                ck, Ck = group_state(g, R, p, W)
                c[:, g.rows] = ck.reshape(n, -1)
                Cs[:, g.rows] = Ck.reshape(n, -1, self.ns)
        return {"R": R, "p": p, "W": W, "c": c, "Cs": Cs}

    def integrate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """TreeArrays.integrate: q (+) v for the stack."""
        out = np.empty_like(q, dtype=float)
        closure_kernels.integrate(np.ascontiguousarray(q, dtype=float), np.ascontiguousarray(v, dtype=float),
                                  self.kinds, self.idx_q, self.idx_v, SMALL_ANGLE, out)
        return out

    def twists_at(self, R: np.ndarray, p: np.ndarray) -> np.ndarray:
        """TreeTwists.twists: (n, a, 6, c) world twists of the active joints per own parameter column."""
        G = np.empty((len(R), len(self.twist_tables[0]), 6, self.twist_tables[3].shape[2]))
        active, placed, parents = self.twist_tables[:3]
        closure_kernels.active_twists(np.ascontiguousarray(R), np.ascontiguousarray(p), active, placed, parents,
                                      self.placement_R, self.placement_p, *self.twist_tables[3:], G)
        return G

    def parameter_rows(self, st: dict) -> np.ndarray:
        """C_theta (n, nnz) at the entries (entry_row, entry_col) that can be nonzero: ClosedChainBatch.
        _parameter_rows, point groups in the kernel."""
        R, p = st["R"], st["p"]
        n = len(R)
        G = self.twists_at(R, p) if len(self.twists.active) else np.zeros((n, 0, 6, 1))
        out = np.zeros((n, len(self.entry_row)))
        for g, point, placed, pairs, frames, dense in zip(self.groups, self.points, self.anchors, self.group_pairs,
                                                          self.group_frames, self.dense):
            if point is not None:
                closure_kernels.point_parameter_rows(R, p, G, *point[0][:2], *placed, *point[2], *point[3], out)
                continue
            sides = [(pk, self.positions[pa], G[:, pa]) if len(self.twists.active) and len(pk) else (None,) * 3
                     for pk, pa in pairs]
            out[:, dense] = parameter_rows(g, R, p, sides, frames, self.nc).reshape(n, -1)
        return out

    def dense_parameter_rows(self, compact: np.ndarray) -> np.ndarray:
        """C_theta (n, m, nc) from its (n, nnz) entries."""
        out = np.zeros((len(compact), self.n_rows, self.nc))
        out[:, self.entry_row, self.entry_col] = compact
        return out

    def newton_step(self, Cs: np.ndarray, c: np.ndarray) -> np.ndarray:
        z = np.empty(c.shape[:1] + Cs.shape[2:])
        arrow_kernels.arrow_newton(np.ascontiguousarray(Cs), np.ascontiguousarray(c), *self.arrow, z)
        return z

    def damped_step(self, Cs: np.ndarray, c: np.ndarray, mu: np.ndarray) -> np.ndarray:
        z = np.empty(c.shape[:1] + Cs.shape[2:])
        arrow_kernels.arrow_damped(np.ascontiguousarray(Cs), np.ascontiguousarray(c),
                                   np.ascontiguousarray(mu, dtype=float), *self.arrow, z)
        return z

    def inverse(self, Cs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(C_s^-1, 1 / (|C_s|_F |C_s^-1|_F)) through the arrow; NaN rows where its shared block is singular."""
        inv, bound = np.empty((len(Cs), Cs.shape[2], Cs.shape[1])), np.empty(len(Cs))
        arrow_kernels.arrow_inverse(np.ascontiguousarray(Cs), *self.arrow, inv, bound)
        return inv, bound

    def frame_solved_columns(self, R0, p0, W, moving, solver, C_theta, ccols, J) -> None:
        """J[:, :, ccols] = -Ad(M^-1) W[:, :, moving] solver[:, moving] C_theta (ClosedChainBatch.frame; C_theta
        (n, nnz) from `parameter_rows`)."""
        sensitivity_kernels.frame_solved_columns(
            np.ascontiguousarray(R0), np.ascontiguousarray(p0), np.ascontiguousarray(W),
            np.asarray(moving, dtype=np.int64), np.ascontiguousarray(solver), np.ascontiguousarray(C_theta),
            self.entry_row, self.entry_col, np.asarray(ccols, dtype=np.int64), J)

    def predicted_moves(self, blocks, dx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(-C_s^-1 C_theta dx (n, ns), max |C_theta dx| (n,)) over the previous pass's (solver, C_theta) blocks."""
        moves, tops = [], []
        for solver, C_theta in blocks:
            dq, top = np.empty(solver.shape[:2]), np.empty(len(solver))
            sensitivity_kernels.predicted_moves(solver, C_theta, self.entry_row, self.entry_col,
                                                np.ascontiguousarray(dx, dtype=float), dq, top)
            moves.append(dq)
            tops.append(top)
        return np.concatenate(moves), np.concatenate(tops)
