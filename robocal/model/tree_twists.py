"""How the free parameters move the joints of a tree, every joint held, for many samples at once.

A placement parameter of joint i twists the frame oMi[parent] jointPlacement(i) (a LOCAL right twist
there, P_joint of robocal.model.kinematics.ModelState), so in the world it is Ad(oMi[parent] jointPlacement)
P_joint_i; an offset of joint i moves it along its world motion column. A joint j then moves with the sum
over the joints supporting it. Each joint's parameters are few (a placement's six components at most, one
offset), so every "active" joint keeps its own short list of free columns instead of all of them: the
arrays stay small (n, n_active, 6, c) and the caller scatters them (robocal.model.closed_chain_batch).
"""
from __future__ import annotations

import copy

import numpy as np

from robocal.model.lie_arrays import adjoint
from robocal.model.tree_arrays import TreeArrays



class TreeTwists:
    """The active joints of a ModelState (those its free placement or offset parameters move).

    active     (a,) joint ids
    columns    (a, c) free-parameter column of each joint's parameters, padded with n_free (a column the
               caller drops)
    """

    def __init__(self, ms, tree: TreeArrays):
        self.tree, self.model = tree, tree.model
        nj, n_free = self.model.njoints, ms.n_free
        self.n_free = n_free
        blocks = ms.P_joint.reshape(nj - 1, 6, n_free)
        own_v = {j: np.arange(tree.idx_v[j], tree.idx_v[j] + tree.nv_j[j]) for j in range(1, nj)}
        used = {j: np.flatnonzero(np.any(blocks[j - 1] != 0.0, axis=0) | np.any(ms.P_offset[own_v[j]] != 0.0, axis=0))
                for j in range(1, nj)}
        self.active = np.array([j for j in range(1, nj) if len(used[j])], dtype=int)
        c = max((len(used[j]) for j in self.active), default=0)
        self.columns = np.full((len(self.active), c), n_free, dtype=int)
        self.blocks = np.zeros((len(self.active), 6, c))
        self.offset_v, self.offset_rows, self.offset_owner = [], [], []
        for a, j in enumerate(self.active):
            cols = used[j]
            self.columns[a, :len(cols)] = cols
            self.blocks[a, :, :len(cols)] = blocks[j - 1][:, cols]
            for iv in own_v[j]:
                if ms.P_offset[iv, cols].any():
                    row = np.zeros(c)
                    row[:len(cols)] = ms.P_offset[iv, cols]
                    self.offset_v.append(int(iv))
                    self.offset_rows.append(row)
                    self.offset_owner.append(a)
        self.offset_v = np.array(self.offset_v, dtype=int)
        self.placed = np.flatnonzero(np.any(self.blocks != 0.0, axis=(1, 2)))   # active through a placement
        self.supports = {j: [a for a, i in enumerate(self.active) if int(i) in tree.supports[j]] for j in range(nj)}

    def at_tree(self, tree: TreeArrays) -> "TreeTwists":
        """These twists on `tree` (the same joints at another pass's placements; the parameter blocks equal)."""
        out = copy.copy(self)
        out.tree, out.model = tree, tree.model
        return out

    @property
    def free_columns(self) -> np.ndarray:
        """The free columns any active joint moves (sorted)."""
        return np.unique(self.columns[self.columns < self.n_free])

    def twists(self, R: np.ndarray, p: np.ndarray) -> np.ndarray:
        """(n, a, 6, c): world twist of each active joint per own parameter column, at the world placements
        R (n, njoints, 3, 3), p (n, njoints, 3) of a sample stack, every joint held."""
        n = len(R)
        G = np.zeros((n, len(self.active)) + self.blocks.shape[1:])
        if len(self.placed):       # placement parameters: Ad(oMi[parent] jointPlacement) times their block
            aR, ap = self.tree.before_motion(R, p, self.active[self.placed])
            G[:, self.placed] = adjoint(aR, ap) @ self.blocks[self.placed]
        if len(self.offset_v):      # an offset moves its joint along the joint's motion column
            cols = self.tree.motion_columns(R, p, self.offset_v)            # (n, 6, n_offsets)
            for k, a in enumerate(self.offset_owner):
                G[:, a] += cols[:, :, k, None] * self.offset_rows[k]
        return G

    def pairs(self, joints) -> tuple[np.ndarray, np.ndarray]:
        """(k_index, a_index): for each of `joints` (by position) every active joint supporting it."""
        ks, as_ = [], []
        for k, j in enumerate(joints):
            for a in self.supports[int(j)]:
                ks.append(k)
                as_.append(a)
        return np.array(ks, dtype=int), np.array(as_, dtype=int)
