"""Forward kinematics, joint-motion columns and integration of a Pinocchio tree at many configurations at once.

Closed-chain assembly needs, at every Newton step of every sample, the placements of the loop anchors and
how they move with the passive joints. Calling Pinocchio per sample costs a few microseconds per call from
Python (constraint models: ~24 us per sample and evaluation for a Stewart platform, see docs/speed.md), so
the tree is walked here once for all samples with whole-array numpy, the joints of one depth and kind together:

    oMi[j] = oMi[parent(j)] jointPlacement(j) M_j(q_j)

Joint kinds: revolute and prismatic (any axis), continuous (q = cos, sin), free-flyer (x y z qx qy qz qw) and
spherical (qx qy qz qw), with Pinocchio's configuration layout and its integrate (q <- q (+) v, v LOCAL).
Other joint kinds are not handled (`supports_tree_arrays`).
"""
from __future__ import annotations

import copy

import numpy as np
import pinocchio as pin

from robocal.model.lie_arrays import cross, quaternion_matrices, skew

KINDS = {**{f"JointModelR{a}": "revolute" for a in "XYZ"}, "JointModelRevoluteUnaligned": "revolute",
         **{f"JointModelRUB{a}": "continuous" for a in "XYZ"}, "JointModelRevoluteUnboundedUnaligned": "continuous",
         **{f"JointModelP{a}": "prismatic" for a in "XYZ"}, "JointModelPrismaticUnaligned": "prismatic",
         "JointModelFreeFlyer": "free", "JointModelSpherical": "spherical"}
SMALL_ANGLE = 1e-4      # below it, the exp maps' coefficients by their Taylor series (error < theta^4 / 120)


def supports_tree_arrays(model: pin.Model) -> bool:
    return all(j.shortname() in KINDS for j in list(model.joints)[1:])


def quaternion_step(quat: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4) of R exp3(w) for quaternions `quat` of R (Hamilton product, x y z w)."""
    theta = np.linalg.norm(w, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(theta < SMALL_ANGLE, 0.5 - theta ** 2 / 48.0, np.sin(0.5 * theta) / theta)
    b = np.concatenate([k[:, None] * w, np.cos(0.5 * theta)[:, None]], axis=1)
    a = quat
    out = np.stack([a[:, 3] * b[:, 0] + a[:, 0] * b[:, 3] + a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                    a[:, 3] * b[:, 1] - a[:, 0] * b[:, 2] + a[:, 1] * b[:, 3] + a[:, 2] * b[:, 0],
                    a[:, 3] * b[:, 2] + a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] + a[:, 2] * b[:, 3],
                    a[:, 3] * b[:, 3] - a[:, 0] * b[:, 0] - a[:, 1] * b[:, 1] - a[:, 2] * b[:, 2]], axis=1)
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def se3_translation_step(w: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(n, 3) translation of exp6([v; w]): V(w) v."""
    theta = np.linalg.norm(w, axis=1)
    small = theta < SMALL_ANGLE
    t2 = np.where(small, 1.0, theta * theta)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(small, 0.5 - theta ** 2 / 24.0, (1.0 - np.cos(theta)) / t2)
        b = np.where(small, 1.0 / 6.0 - theta ** 2 / 120.0, (theta - np.sin(theta)) / (t2 * theta))
    wxv = cross(w, v)
    return v + a[:, None] * wxv + b[:, None] * cross(w, wxv)


class TreeArrays:
    """The tree of a Pinocchio model, evaluated on stacks of configurations q (n, nq)."""

    def __init__(self, model: pin.Model):
        self.model = model
        self.njoints = model.njoints
        self.parents = [int(model.parents[j]) for j in range(self.njoints)]
        self.kinds = [None] + [KINDS[model.joints[j].shortname()] for j in range(1, self.njoints)]
        self.idx_q = [model.joints[j].idx_q for j in range(self.njoints)]
        self.idx_v = [model.joints[j].idx_v for j in range(self.njoints)]
        self.nv_j = [model.joints[j].nv for j in range(self.njoints)]
        self._read_placements(model)
        self.axis = np.zeros((self.njoints, 3))          # revolute: rotation axis, prismatic: direction (joint frame)
        neutral = pin.neutral(model)
        for j in range(1, self.njoints):
            name = model.joints[j].shortname()
            if name[-1] in "XYZ" and self.kinds[j] != "free":
                self.axis[j, "XYZ".index(name[-1])] = 1.0
            elif "Unaligned" in name:      # the joint's own motion subspace (constant for these kinds)
                joint_data = model.joints[j].createData()
                model.joints[j].calc(joint_data, neutral)
                S = np.asarray(joint_data.S).reshape(6)
                self.axis[j] = S[:3] if self.kinds[j] == "prismatic" else S[3:]
        self.axis_skew = skew(self.axis)
        self.identity = np.eye(3)
        self.parent_array, self.q_array = np.array(self.parents), np.array(self.idx_q)
        self.levels = self._levels()
        plain = [j for j in range(1, self.njoints) if self.kinds[j] in ("revolute", "prismatic")]
        self.plain_q = np.array([self.idx_q[j] for j in plain], dtype=int)
        self.plain_v = np.array([self.idx_v[j] for j in plain], dtype=int)
        self.other_joints = [j for j in range(1, self.njoints) if j not in plain]
        # per velocity coordinate: owning joint, coordinate within it, and its kind (0 prismatic, 1 revolute or
        # continuous, 2 free-flyer translation, 3 free-flyer or spherical rotation)
        self.v_owner, self.v_dof, self.v_kind = (np.zeros(model.nv, dtype=int) for _ in range(3))
        for j in range(1, self.njoints):
            for k in range(self.nv_j[j]):
                iv, kind = self.idx_v[j] + k, self.kinds[j]
                self.v_owner[iv], self.v_dof[iv] = j, (k - 3 if kind == "free" and k >= 3 else k)
                self.v_kind[iv] = {"prismatic": 0, "revolute": 1, "continuous": 1}.get(
                    kind, 2 if kind == "free" and k < 3 else 3)
        # motion columns: the direction of each coordinate is column `v_along` of its joint's rotation (for the
        # one-dof kinds along a coordinate axis, and every free-flyer or spherical coordinate)
        one_dof = self.v_kind <= 1
        self.v_aligned = ~one_dof | (np.abs(self.axis[self.v_owner]).sum(axis=1) == 1.0) & (
            self.axis[self.v_owner].max(axis=1) == 1.0)
        self.v_along = np.where(one_dof, np.argmax(self.axis[self.v_owner], axis=1), self.v_dof)
        self.v_turning = (self.v_kind == 1) | (self.v_kind == 3)
        self.axis_skew2 = self.axis_skew @ self.axis_skew
        # supports[j]: the joints from the root to j; support_v[j]: their velocity indices
        self.supports = [set(int(i) for i in model.supports[j]) for j in range(self.njoints)]
        self.support_v = []
        for j in range(self.njoints):
            cols = [np.arange(self.idx_v[i], self.idx_v[i] + self.nv_j[i]) for i in list(model.supports[j])[1:]]
            self.support_v.append(np.concatenate(cols).astype(int) if cols else np.zeros(0, dtype=int))

    def _read_placements(self, model: pin.Model) -> None:
        self.placement_R = np.array([model.jointPlacements[j].rotation for j in range(self.njoints)])
        self.placement_p = np.array([model.jointPlacements[j].translation for j in range(self.njoints)])
        self.unrotated = np.all(self.placement_R == np.eye(3), axis=(1, 2))

    def at_placements(self, model: pin.Model) -> "TreeArrays":
        """This tree with the joint placements of `model` (same joints, e.g. another parameter vector): the
        structure is kept, only the placements are read again."""
        out = copy.copy(self)
        out.model = model
        out._read_placements(model)
        return out

    def _levels(self) -> list[tuple[str, int, np.ndarray]]:
        """The joints grouped by depth, kind and axis (0, 1, 2 along x, y, z; -1 other), root first: one set
        of array operations per group."""
        depth = [0] * self.njoints
        groups: dict = {}
        for j in range(1, self.njoints):
            depth[j] = depth[self.parents[j]] + 1
            kind = self.kinds[j]
            aligned = np.flatnonzero(self.axis[j] == 1.0)
            axis = int(aligned[0]) if len(aligned) == 1 and np.abs(self.axis[j]).sum() == 1.0 else -1
            single = j if kind in ("free", "spherical") else 0     # those one by one
            groups.setdefault((depth[j], kind, axis, single), []).append(j)
        return [(key[1], key[2], np.array(js)) for key, js in sorted(groups.items())]

    def placements(self, q: np.ndarray):
        """World placements of the joints at q (n, nq): R (n, njoints, 3, 3), p (n, njoints, 3)."""
        n, nj = len(q), self.njoints
        R, p = np.empty((n, nj, 3, 3)), np.empty((n, nj, 3))
        R[:, 0], p[:, 0] = np.eye(3), 0.0
        for kind, axis, js in self.levels:
            aR, ap = self.before_motion(R, p, js)
            iq = self.q_array[js]
            if kind in ("revolute", "continuous"):
                if kind == "revolute":
                    c, s = np.cos(q[:, iq]), np.sin(q[:, iq])
                else:
                    c, s = q[:, iq], q[:, iq + 1]
                if axis >= 0:   # about a coordinate axis: two columns of aR turn into each other (no 3x3 products)
                    i, k = (axis + 1) % 3, (axis + 2) % 3
                    c, s = c[..., None], s[..., None]
                    B = np.empty((n, len(js), 3, 3))
                    B[..., i] = c * aR[..., i] + s * aR[..., k]
                    B[..., k] = c * aR[..., k] - s * aR[..., i]
                    B[..., axis] = aR[..., axis]
                    R[:, js] = B
                else:
                    Rj = (self.identity + s[..., None, None] * self.axis_skew[js]
                          + (1.0 - c)[..., None, None] * self.axis_skew2[js])
                    R[:, js] = aR @ Rj
                p[:, js] = ap
            elif kind == "prismatic":
                R[:, js] = aR
                direction = aR[..., axis] if axis >= 0 else (aR @ self.axis[js][..., None])[..., 0]
                p[:, js] = ap + q[:, iq, None] * direction
            else:   # one free-flyer or spherical joint
                aR, ap, i = aR[..., 0, :, :], ap[..., 0, :], iq[0]     # (3, 3) on the root, else (n, 3, 3)
                if kind == "free":
                    Rq = quaternion_matrices(q[:, i + 3:i + 7])
                    R[:, js[0]] = Rq if aR.ndim == 2 and not (aR - self.identity).any() else aR @ Rq
                    p[:, js[0]] = ap + np.einsum("...ij,nj->ni", aR, q[:, i:i + 3])
                else:
                    R[:, js[0]], p[:, js[0]] = aR @ quaternion_matrices(q[:, i:i + 4]), ap
        return R, p

    def before_motion(self, R: np.ndarray, p: np.ndarray, js: np.ndarray):
        """oMi[parent] jointPlacement of the joints js: ((n, k, 3, 3), (n, k, 3)), or constant (k, 3, 3), (k, 3)
        for joints on the root; from the world placements R, p of their parents."""
        par = self.parent_array[js]
        if not par.any():
            return self.placement_R[js], self.placement_p[js]
        Rp = R[:, par]
        aR = Rp if self.unrotated[js].all() else Rp @ self.placement_R[js]
        if not self.placement_p[js].any():
            return aR, p[:, par]
        return aR, np.einsum("nkij,kj->nki", Rp, self.placement_p[js]) + p[:, par]

    def motion_columns(self, R: np.ndarray, p: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """(n, 6, len(columns)) WORLD twists [v; w] of the velocity coordinates `columns` (each joint's motion
        subspace carried by its world placement Ad(oMi) S): a direction d in the world (a column of the joint's
        rotation for the kinds along a coordinate axis) gives [d; 0] for a translation and [p x d; d] for a
        rotation about the joint's origin p."""
        columns = np.asarray(columns, dtype=int)
        j, aligned, turning = self.v_owner[columns], self.v_aligned[columns], self.v_turning[columns]
        d = np.swapaxes(R[:, j, :, self.v_along[columns]], 0, 1)   # indices split by a slice come first: swap
        if not aligned.all():
            other = np.flatnonzero(~aligned)
            d[:, other] = np.einsum("nkij,kj->nki", R[:, j[other]], self.axis[j[other]])
        out = np.empty((len(R), len(columns), 6))
        cross(p[:, j], d, out=out[:, :, :3])
        if not turning.all():
            out[:, ~turning, :3] = d[:, ~turning]
        out[:, :, 3:] = d * turning[:, None]
        return np.swapaxes(out, 1, 2)

    def integrate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """q (+) v for q (n, nq), v (n, nv), as pin.integrate sample by sample (to rounding)."""
        out = q.copy()
        out[:, self.plain_q] += v[:, self.plain_v]      # one-dof revolute and prismatic joints at once
        for j in self.other_joints:
            iq, iv, kind = self.idx_q[j], self.idx_v[j], self.kinds[j]
            if kind == "continuous":
                c, s = np.cos(v[:, iv]), np.sin(v[:, iv])
                out[:, iq], out[:, iq + 1] = q[:, iq] * c - q[:, iq + 1] * s, q[:, iq + 1] * c + q[:, iq] * s
            elif kind == "free":
                lin, ang = v[:, iv:iv + 3], v[:, iv + 3:iv + 6]
                R = quaternion_matrices(q[:, iq + 3:iq + 7])
                out[:, iq:iq + 3] += np.einsum("nij,nj->ni", R, se3_translation_step(ang, lin))
                out[:, iq + 3:iq + 7] = quaternion_step(q[:, iq + 3:iq + 7], ang)
            else:
                out[:, iq:iq + 4] = quaternion_step(q[:, iq:iq + 4], v[:, iv:iv + 3])
        return out
