"""Forward kinematics, joint-motion columns and integration of a Pinocchio tree at many configurations at once.

Closed-chain assembly needs, at every Newton step of every sample, the placements of the loop anchors and
how they move with the passive joints. Calling Pinocchio per sample costs a few microseconds per call from
Python (constraint models: ~20 us per sample and step for a Stewart platform, see benchmarks/closed_chain.py),
so the tree is walked here once for all samples, joint by joint, with whole-array numpy:

    oMi[j] = oMi[parent(j)] jointPlacement(j) M_j(q_j)

Joint kinds: revolute and prismatic (any axis), continuous (q = cos, sin), free-flyer (x y z qx qy qz qw) and
spherical (qx qy qz qw), with Pinocchio's configuration layout and its integrate (q <- q (+) v, v LOCAL).
The motion subspaces are read from Pinocchio at the neutral configuration, as robocal.model.batch_kinematics
does. Other joint kinds are not handled (`supports_tree_arrays`).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.model.lie_arrays import skew

LOCAL = pin.ReferenceFrame.LOCAL
KINDS = {**{f"JointModelR{a}": "revolute" for a in "XYZ"}, "JointModelRevoluteUnaligned": "revolute",
         **{f"JointModelRUB{a}": "continuous" for a in "XYZ"}, "JointModelRevoluteUnboundedUnaligned": "continuous",
         **{f"JointModelP{a}": "prismatic" for a in "XYZ"}, "JointModelPrismaticUnaligned": "prismatic",
         "JointModelFreeFlyer": "free", "JointModelSpherical": "spherical"}
SMALL_ANGLE = 1e-4      # below it, the exp maps' coefficients by their Taylor series (error < theta^4 / 120)


def supports_tree_arrays(model: pin.Model) -> bool:
    return all(j.shortname() in KINDS for j in list(model.joints)[1:])


def quaternion_matrices(quat: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations of quaternions (n, 4), x y z w, as Eigen's toRotationMatrix."""
    x, y, z, w = quat[:, 0], quat[:, 1], quat[:, 2], quat[:, 3]
    out = np.empty((len(quat), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
    return out


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
    wxv = np.cross(w, v)
    return v + a[:, None] * wxv + b[:, None] * np.cross(w, wxv)


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
        self.placement_R = np.array([model.jointPlacements[j].rotation for j in range(self.njoints)])
        self.placement_p = np.array([model.jointPlacements[j].translation for j in range(self.njoints)])
        data = model.createData()
        pin.computeJointJacobians(model, data, pin.neutral(model))
        self.axis = np.zeros((self.njoints, 3))          # revolute: rotation axis, prismatic: direction (joint frame)
        for j in range(1, self.njoints):
            if self.kinds[j] in ("revolute", "continuous", "prismatic"):
                S = pin.getJointJacobian(model, data, j, LOCAL)[:, self.idx_v[j]]
                self.axis[j] = S[3:] if self.kinds[j] != "prismatic" else S[:3]
        self.axis_skew = skew(self.axis)
        self.axis_skew2 = self.axis_skew @ self.axis_skew
        # support_v[j]: the velocity indices of the joints from the root to j
        self.support_v = []
        for j in range(self.njoints):
            cols = [np.arange(self.idx_v[i], self.idx_v[i] + self.nv_j[i]) for i in list(model.supports[j])[1:]]
            self.support_v.append(np.concatenate(cols).astype(int) if cols else np.zeros(0, dtype=int))

    def placements(self, q: np.ndarray, joints=None):
        """World placements of the joints at q (n, nq): R (n, njoints, 3, 3), p (n, njoints, 3) and the
        placements before each joint's own motion A = oMi[parent] jointPlacement (AR, Ap, same shapes).
        `joints`: the joints needed (with their supports); default all."""
        n, nj = len(q), self.njoints
        R, p = np.empty((n, nj, 3, 3)), np.empty((n, nj, 3))
        AR, Ap = np.empty((n, nj, 3, 3)), np.empty((n, nj, 3))
        R[:, 0], p[:, 0] = np.eye(3), 0.0
        needed = range(1, nj) if joints is None else sorted({i for j in joints for i in self.model.supports[j]} - {0})
        for j in needed:
            par, iq, kind = self.parents[j], self.idx_q[j], self.kinds[j]
            if par == 0:
                aR, ap = self.placement_R[j], self.placement_p[j]
            else:
                aR = R[:, par] @ self.placement_R[j]
                ap = np.einsum("nij,j->ni", R[:, par], self.placement_p[j]) + p[:, par]
            AR[:, j], Ap[:, j] = aR, ap
            if kind in ("revolute", "continuous"):
                if kind == "revolute":
                    c, s = np.cos(q[:, iq]), np.sin(q[:, iq])
                else:
                    c, s = q[:, iq], q[:, iq + 1]
                Rj = np.eye(3) + s[:, None, None] * self.axis_skew[j] + (1.0 - c)[:, None, None] * self.axis_skew2[j]
                R[:, j], p[:, j] = aR @ Rj, ap
            elif kind == "prismatic":
                R[:, j] = aR
                p[:, j] = ap + q[:, iq, None] * (aR @ self.axis[j])
            elif kind == "free":
                R[:, j] = aR @ quaternion_matrices(q[:, iq + 3:iq + 7])
                p[:, j] = ap + (np.einsum("nij,nj->ni", aR, q[:, iq:iq + 3]) if aR.ndim == 3 else q[:, iq:iq + 3] @ aR.T)
            else:   # spherical
                R[:, j], p[:, j] = aR @ quaternion_matrices(q[:, iq:iq + 4]), ap
        return R, p, AR, Ap

    def motion_columns(self, R: np.ndarray, p: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """(n, 6, len(columns)) WORLD twists [v; w] of the velocity coordinates `columns` (each joint's motion
        subspace carried by its world placement Ad(oMi) S)."""
        n = len(R)
        out = np.zeros((n, 6, len(columns)))
        owner = {}
        for j in range(1, self.njoints):
            for k in range(self.nv_j[j]):
                owner[self.idx_v[j] + k] = (j, k)
        for col, iv in enumerate(columns):
            j, k = owner[int(iv)]
            kind = self.kinds[j]
            if kind == "prismatic":
                out[:, :3, col] = R[:, j] @ self.axis[j]
            elif kind in ("revolute", "continuous"):
                w = R[:, j] @ self.axis[j]
                out[:, :3, col], out[:, 3:, col] = np.cross(p[:, j], w), w
            elif kind == "free" and k < 3:
                out[:, :3, col] = R[:, j, :, k]
            else:       # an angular coordinate of a free-flyer or spherical joint
                w = R[:, j, :, k - 3 if kind == "free" else k]
                out[:, :3, col], out[:, 3:, col] = np.cross(p[:, j], w), w
        return out

    def integrate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """q (+) v for q (n, nq), v (n, nv), as pin.integrate sample by sample (to rounding)."""
        out = q.copy()
        for j in range(1, self.njoints):
            iq, iv, kind = self.idx_q[j], self.idx_v[j], self.kinds[j]
            if kind in ("revolute", "prismatic"):
                out[:, iq] += v[:, iv]
            elif kind == "continuous":
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
