"""How a frame's parent joint moves with the free parameters at n samples, kept as its parts.

The (n, 6, n_free) Jacobian of the joint's LOCAL twist is the kinematic regressors times the twist map
(a GEMM, run joint by joint when each joint's rows reach columns of their own: GemmBlocks) plus a few
additive column blocks (the frame's own placement, the base, compliance and backlash).
A residual only ever needs D @ J, with D its (n, d, 6) derivative: `project` applies D to the regressors
first ((n, d, 6) @ (n, 6, s), small) and lets the GEMM write straight into the residual's rows of the
problem's Jacobian, so the (n, 6, n_free) array is never formed (at 10^4 samples: 26 MB written and read
once less per pass).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class JointJacobianParts:
    """n samples, n_free columns; regressors (n, 6, s) over the s columns that can be non-zero and
    tmap (s, n_free), or None when no joint parameter is free; terms: [(columns, A)] with A (6, k) (the
    same at every sample) or (n, 6, k), added to those columns. `blocks` (GemmBlocks), when given, says
    which columns each joint's six rows of tmap can reach: the GEMM then runs joint by joint."""

    n: int
    n_free: int
    regressors: np.ndarray | None
    tmap: np.ndarray | None
    terms: list = field(default_factory=list)
    blocks: "GemmBlocks | None" = None

    def add(self, cols, block: np.ndarray) -> None:
        self.terms.append((cols, block))

    def project(self, M: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """(n, d, n_free) = M @ J for M (n, d, 6), into `out` when given."""
        n, d = self.n, M.shape[1]
        if out is not None and not out.flags.c_contiguous:     # the GEMM writes through a flat view
            out[...] = self.project(M)
            return out
        out = np.empty((n, d, self.n_free)) if out is None else out
        if self.regressors is None:
            out[...] = 0.0
        else:
            s = self.regressors.shape[2]
            folded = np.matmul(M, self.regressors).reshape(n * d, s)      # (n d, s)
            flat = out.reshape(n * d, self.n_free)
            if self.blocks is None:
                np.matmul(folded, self.tmap, out=flat)
            else:
                self.blocks.multiply(folded, self.tmap, flat)
        flat_M = M.reshape(n * d, 6)
        for cols, block in self.terms:
            if block.ndim == 2:      # the same at every sample: one GEMM, not n small products
                out[:, :, cols] += (flat_M @ block).reshape(n, d, -1)
            else:
                out[:, :, cols] += M @ block
        return out

    def dense(self) -> np.ndarray:
        """The (n, 6, n_free) Jacobian itself."""
        return self.project(np.broadcast_to(np.eye(6), (self.n, 6, 6)))


CHUNK_ROWS = 6144     # rows of the block GEMM at a time: the strided column reads stay in cache


@dataclass
class GemmBlocks:
    """The twist map's block structure: `rows[k]` (six rows of tmap, one joint) reach only `cols[k]` (a slice
    or indices), no two joints share a column, and `uncovered` columns are reached by none. A joint's
    placement moves its own parameters only, so folded @ tmap is a few (rows x 6) @ (6 x k) products instead
    of one (rows x s) @ (s x n_free): on a 6-joint arm ~6 times fewer flops."""

    rows: list
    cols: list
    uncovered: np.ndarray

    def multiply(self, folded: np.ndarray, tmap: np.ndarray, flat: np.ndarray) -> None:
        """flat = folded @ tmap, block by block, in chunks of rows."""
        if len(self.uncovered):
            flat[:, self.uncovered] = 0.0
        parts = [(r, c, tmap[r, c]) for r, c in zip(self.rows, self.cols)]
        for r0 in range(0, len(folded), CHUNK_ROWS):
            chunk = slice(r0, min(r0 + CHUNK_ROWS, len(folded)))
            for r, c, B in parts:
                if isinstance(c, slice):
                    np.matmul(folded[chunk, r], B, out=flat[chunk, c])
                else:
                    flat[chunk, c] = folded[chunk, r] @ B
