"""Frame poses and parameter Jacobians of every sample at once, for serial (tree) robots.

The per-sample path (robocal.model.kinematics.SampleState) answers one sample and one frame at a time
through Python objects; here the only per-sample work is Pinocchio's: forward kinematics and the frame's
kinematic regressor. Everything else is whole-array numpy over the samples:

- the regressor's LOCAL block of joint j is Ad(X_j), X_j = oMf^-1 oMi[parent(j)] jointPlacement(j)
  (see the Pinocchio notes, section 2), so it already holds the frame relative to every supporting joint;
- the LOCAL frame Jacobian's column of a one-dof joint with a constant motion subspace S_j (revolute,
  prismatic, continuous) is Ad(X_j) S_j, since exp(S_j q) leaves S_j unchanged;
- the frame's pose is jointPlacement(j0) X_j0^-1 for the root-most supporting joint j0 (its parent is
  the universe, at the identity).

The parameter Jacobian then follows SampleState's formula term by term (offsets, compliance, backlash,
placements through the regressor, joint tilts (robocal.model.joint_tilt_arrays: their placements set per
sample before Pinocchio runs), frame and base placements). Robots with loops or other joint kinds keep the
per-sample path (`supports_batch`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.model.joint_jacobian_parts import GemmBlocks, JointJacobianParts
from robocal.model.joint_tilt import perpendicular_moments
from robocal.model.joint_tilt_arrays import TiltArrays
from robocal.model.lie_arrays import adjoint_inverse, transpose
from robocal.model.robot import ConfigurationMap
from robocal.model.state_layout import contiguous

LOCAL = pin.ReferenceFrame.LOCAL
CONSTANT_SUBSPACE = {"JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned",
                     "JointModelRUBX", "JointModelRUBY", "JointModelRUBZ", "JointModelRevoluteUnboundedUnaligned",
                     "JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned"}


def supports_batch(ms) -> bool:
    """Whether a ModelState's samples can be evaluated here (serial, plain one-dof joints)."""
    if ms.loops is not None:
        return False
    memo = ms.robot.__dict__.setdefault("_constant_subspace", {})    # joint kinds never change: once per model
    key = ms.model.njoints
    if key not in memo:
        memo[key] = all(j.shortname() in CONSTANT_SUBSPACE for j in list(ms.model.joints)[1:])
    return memo[key]


@dataclass
class FrameArrays:
    """One frame at n samples: world pose (R, p) (measurement frame), pose on the robot (R0, p0), and how it
    moves with the free parameters: `jacobian` (n, 6, n_free) is the LOCAL twist of the frame's parent joint
    per free parameter and the frame's own LOCAL twist is `to_frame` @ jacobian (a constant 6x6: the frame's
    placement on its joint), so a residual folds `to_frame` into its (n, d, 6) derivative instead of a pass
    over the (n, 6, n_free) array. A serial robot keeps that Jacobian as its parts (`joint`,
    joint_jacobian_parts.py) and `jacobian` is None: `project(M)` gives M @ J either way. Both are valid until
    the next `frame` call for the same frame on the same problem; None when only poses were asked for."""

    R: np.ndarray
    p: np.ndarray
    R0: np.ndarray
    p0: np.ndarray
    jacobian: np.ndarray | None
    to_frame: np.ndarray | None = None
    joint: JointJacobianParts | None = None     # the parent joint's Jacobian as its parts (serial robots)

    def project(self, M: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """(n, d, n_free) = M @ `jacobian` for M (n, d, 6), without forming `jacobian` when it is kept as parts."""
        if self.joint is not None:
            return self.joint.project(M, out)
        return np.matmul(M, self.jacobian, out=out)


class SampleConstants:
    """What does not change with the parameters, computed once per problem: each sample's gravity torque
    at its readings (the compliance load), the tilted joints' gravity moments (`tilt_moments`) and the joints'
    motion subspaces."""

    def __init__(self, robot, joint_names, values: np.ndarray, needs_gravity: bool, v_index: np.ndarray):
        self.values = values.copy()
        self.configurations = robot_configuration_map(robot, joint_names)
        self.tau = None
        model = robot.model
        data = model.createData()      # one workspace for these and for the batched passes (same structure)
        if needs_gravity:
            self.tau = np.array([pin.computeGeneralizedGravity(model, data, q)[v_index]
                                 for q in self.configurations(values)])
        pin.computeJointJacobians(model, data, pin.neutral(model))
        self.subspace = np.zeros((model.nv, 6))      # row v: S of the joint owning velocity v (LOCAL)
        for jid in range(1, model.njoints):
            jm = model.joints[jid]
            if jm.nv:
                J = pin.getJointJacobian(model, data, jid, LOCAL)
                self.subspace[jm.idx_v:jm.idx_v + jm.nv] = J[:, jm.idx_v:jm.idx_v + jm.nv].T
        self.regressors: dict = {}      # joint id -> (samples, q, joint_key, regressors, derived, tilts) of the last pass
        self.offset_map = None          # (P_offset, its twist-map rows, any non-zero) of the last layout
        self.gemm_plans: dict = {}      # joint id -> (layout, its regressor's columns that can be non-zero, GemmBlocks)
        self.data = data                # Pinocchio workspace of the batched passes (any model of this structure)
        self._moments: dict = {}        # tilted joints -> (n, k, 3) gravity moments
        self.scratch = None             # a model copy whose tilted joints' placements move per sample

    def tilt_moments(self, robot, tilts) -> np.ndarray:
        """(n, n tilted joints, 3): the perpendicular gravity moments of `tilts` (a JointTilts) at every sample's
        readings, with the nominal model (robocal.model.joint_tilt), worked out once per set of joints."""
        joints = tuple(jid for jid, _, _ in tilts.entries)
        hit = self._moments.get(joints)
        if hit is None:
            model, data = robot.model, tilts.gdata
            hit = self._moments[joints] = np.array([perpendicular_moments(model, data, q, list(joints), tilts.axes)
                                                    for q in self.configurations(self.values)])
        return hit

    def matches(self, values: np.ndarray) -> bool:
        return self.values.shape == values.shape and np.array_equal(self.values, values)


def robot_configuration_map(robot, joint_names):
    """Readings (n, n_read) -> configurations (n, nq), with the robot's ConfigurationMap's index work."""
    cmap = ConfigurationMap(robot, joint_names)

    def configurations(values: np.ndarray) -> np.ndarray:
        q = np.tile(cmap.q0, (len(values), 1))
        q[:, cmap.plain_q] = values[:, cmap.plain_k]
        if len(cmap.cont_k):
            q[:, cmap.cont_q] = np.cos(values[:, cmap.cont_k])
            q[:, cmap.cont_q + 1] = np.sin(values[:, cmap.cont_k])
        return q
    return configurations


CACHE_BYTES = 64 * 2 ** 20     # regressors kept between passes (fits whose free parameters leave FK alone)


class BatchKinematics:
    """One ModelState evaluated at many samples; `frame(name, samples)` -> FrameArrays."""

    def __init__(self, ms, constants: SampleConstants, values: np.ndarray, directions: np.ndarray | None):
        self.ms, self.constants = ms, constants
        self.model = ms.model
        link = values if directions is None else values + ms.backlash * directions
        link = link + ms.offsets
        if constants.tau is not None:
            link = link - ms.compliance * constants.tau
        self.q = constants.configurations(link)
        self.directions = directions
        self._twist_map, self._moves_joints = None, False
        self.tilts = (TiltArrays(ms.tilts, constants.tilt_moments(ms.robot, ms.tilts)) if ms.tilts is not None
                      else None)

    def regressors(self, jid: int, samples: np.ndarray) -> np.ndarray:
        """(n, 6, 6 n_joints) LOCAL kinematic regressors of joint jid's frame at the samples, cached while the
        configurations and the values that place the joints (ModelState.joint_key) are unchanged. A frame's
        own placement is not part of the key: a fit that moves only a tool or marker frame (the registration,
        a tool-only fit) runs Pinocchio once (see `frame`)."""
        q = self.q[samples]
        model = self.model
        robot, placements = self.ms.joint_key        # the joint placements, as the values that set them
        tilt_key = None if self.tilts is None else (self.tilts.joints, self.tilts.key)
        hit = self.constants.regressors.get(jid)
        if (hit is not None and hit[2][0] is robot and np.array_equal(hit[0], samples) and
                np.array_equal(hit[1], q) and np.array_equal(hit[2][1], placements) and hit[5] == tilt_key):
            return hit[3]
        # own Data (the per-sample path's cached state stays valid), kept between passes: a Data depends on
        # the model's structure only, which every calibrated copy shares
        data = self.constants.data
        if data is None:
            data = self.constants.data = model.createData()
        shape = (len(samples), 6, 6 * (model.njoints - 1))
        out = hit[3] if hit is not None and hit[3].shape == shape else np.empty(shape)   # the old entry's memory
        fk, regressor = pin.forwardKinematics, pin.computeJointKinematicRegressor
        if self.tilts is None:
            for row, qi in enumerate(q):
                fk(model, data, qi)
                out[row] = regressor(model, data, jid, LOCAL)
        else:       # each sample's tilted placements first, in the problem's scratch copy of the model
            model, apply = self.tilted_model(), self.tilts.apply
            placements = model.jointPlacements
            for row, (i, qi) in enumerate(zip(samples, q)):
                apply(placements, i)
                fk(model, data, qi)
                out[row] = regressor(model, data, jid, LOCAL)
        if out.nbytes <= CACHE_BYTES:
            self.constants.regressors[jid] = (samples.copy(), q, self.ms.joint_key, out, {}, tilt_key)
        return out

    def tilted_model(self):
        """The problem's scratch copy of the model (SampleConstants.scratch) set to this model's joint placements
        (each call: another pass may have used it since); the tilted joints' are then set per sample. A copy of
        the model per pass would cost more than the pass's forward kinematics."""
        scratch = self.constants.scratch
        if scratch is None or scratch.njoints != self.model.njoints:
            scratch = self.constants.scratch = self.model.copy()
        for jid in range(1, self.model.njoints):
            scratch.jointPlacements[jid] = self.model.jointPlacements[jid]
        return scratch

    def derived(self, jid: int, reg: np.ndarray) -> dict:
        """What is worked out from joint jid's regressors `reg` (its poses, their supporting columns, ...), kept
        with them: a pass that reuses the regressors reuses these (a fresh dict when they are not kept)."""
        hit = self.constants.regressors.get(jid)
        return hit[4] if hit is not None and hit[3] is reg else {}

    def joint_poses(self, jid: int, reg: np.ndarray, samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(R (n, 3, 3), p (n, 3)): joint jid's poses on the robot from its regressors `reg` at the samples, kept
        with them (the same key decides both: a pass that reuses the regressors reuses the poses)."""
        kept = self.derived(jid, reg)
        if "poses" in kept:
            return kept["poses"]
        model = self.model
        j0 = model.supports[jid][1]
        block = reg[:, :, 6 * (j0 - 1):6 * j0]     # Ad(X_j0), X_j0 = oMi^-1 jointPlacement(j0)
        RX, B = block[:, 3:, 3:], block[:, :3, 3:]         # B = [pX]x RX: pX's entries from three rows
        pX = np.stack([np.einsum("nk,nk->n", B[:, 2], RX[:, 1]), np.einsum("nk,nk->n", B[:, 0], RX[:, 2]),
                       np.einsum("nk,nk->n", B[:, 1], RX[:, 0])], axis=-1)
        tilted = None if self.tilts is None else self.tilts.root_placement(j0, samples)
        if tilted is None:
            root = model.jointPlacements[j0]
            Ri = root.rotation @ transpose(RX)
            pi = root.translation - np.einsum("nij,nj->ni", Ri, pX)
        else:                                   # the root joint tilts: its placement differs per sample
            Ri = tilted[0] @ transpose(RX)
            pi = tilted[1] - np.einsum("nij,nj->ni", Ri, pX)
        kept["poses"] = Ri, pi
        return Ri, pi

    def twist_map(self, ms) -> np.ndarray:
        """(6 n_joints, n_free): d(placement twists)/d(free parameters), with each offset column written as
        its joint's motion subspace S_j (a joint turning by dq moves the frame like a placement twist S_j dq)."""
        if self._twist_map is None:
            kept = self.constants.offset_map           # the offsets' part: structure only, kept per layout
            if kept is None or kept[0] is not ms.P_offset:
                S = self.constants.subspace                   # (nv, 6); one-dof joints: v = joint - 1
                offsets = (S[:, :, None] * ms.P_offset[:, None, :]).reshape(6 * len(S), ms.n_free)
                kept = self.constants.offset_map = (ms.P_offset, offsets, bool(offsets.any()))
            self._twist_map = kept[1] + ms.P_joint if ms.has_joint_params else kept[1]
            self._moves_joints = ms.has_joint_params or kept[2]
        return self._twist_map

    def frame(self, frame, samples, jacobian: bool = True) -> FrameArrays:
        """The frame at the samples; without `jacobian`, FrameArrays.jacobian is None (poses only)."""
        ms, model = self.ms, self.model
        fid = frame if isinstance(frame, (int, np.integer)) else ms.robot.frame_id(frame)
        samples = np.asarray(samples, dtype=int)
        ordered = len(samples) < 2 or bool(np.all(samples[1:] > samples[:-1]))
        unique, back = (samples, None) if ordered else np.unique(samples, return_inverse=True)
        n, nj = len(unique), model.njoints - 1
        parent = model.frames[fid].parentJoint
        placement = model.frames[fid].placement
        if parent == 0:      # fixed to the root: no joint moves it; its "joint" is the robot's root frame
            reg = np.zeros((n, 6, 6 * nj))
            Ri, pi = np.broadcast_to(np.eye(3), (n, 3, 3)), np.zeros((n, 3))
        else:
            reg = self.regressors(parent, unique)
            Ri, pi = self.joint_poses(parent, reg, unique)
        # a stack times one matrix as one (3n x 3) GEMM: several times faster than matmul's broadcasting
        Ri = np.ascontiguousarray(Ri)
        R0 = (Ri.reshape(-1, 3) @ placement.rotation).reshape(Ri.shape)
        p0 = pi + (Ri.reshape(-1, 3) @ placement.translation).reshape(pi.shape)
        Rb, pb = ms.base.rotation, ms.base.translation
        R = Rb @ R0
        p = p0 @ Rb.T + pb
        joint = self.joint_jacobian(fid, unique, reg, Ri, pi) if jacobian else None
        to_frame = placement.inverse().toActionMatrix()
        if back is None:
            return FrameArrays(R, p, R0, p0, None, to_frame, joint)
        return FrameArrays(R[back], p[back], R0[back], p0[back], None if joint is None else joint.dense()[back],
                           to_frame)

    def joint_jacobian(self, fid: int, samples: np.ndarray, reg: np.ndarray, Ri: np.ndarray,
                       pi: np.ndarray) -> JointJacobianParts:
        """LOCAL twist of frame fid's parent joint (pose (Ri, pi) on the robot) per free parameter at the
        samples, as its parts (joint_jacobian_parts.py); frame and base columns are carried into the joint's
        frame."""
        ms, model = self.ms, self.model
        n, nj, nf = len(samples), model.njoints - 1, ms.n_free
        tmap = self.twist_map(ms)
        parts = JointJacobianParts(n, nf, None, None)
        if self._moves_joints:
            # offsets act through the joints' columns Ad(X_j) S_j: folded into the placement map, one product
            # serves both (regressors times a (6 n_joints, n_free) map, joint by joint: GemmBlocks); only the
            # joints that support the frame have non-zero regressor columns (a branched tree: the others are
            # skipped, same product)
            parent = model.frames[fid].parentJoint
            kept = self.derived(parent, reg)
            plan = self.constants.gemm_plans.get(parent)
            if plan is None or plan[0] is not ms.layout:
                plan = self.constants.gemm_plans[parent] = (ms.layout, supporting_columns(model, parent),
                                                            gemm_blocks(model, ms, parent))
            _, support, parts.blocks = plan
            if len(support) == 6 * nj:
                parts.regressors, parts.tmap = reg, tmap
            else:
                if "support" not in kept:
                    kept["support"] = reg[:, :, support]
                parts.regressors, parts.tmap = kept["support"], tmap[support]
        if self.tilts is not None and model.frames[fid].parentJoint:
            self.tilts.add_terms(parts, reg, samples, ms.P_joint, model.supports[model.frames[fid].parentJoint])
        if ms.compliance_cols or ms.backlash_cols:
            Jq = np.einsum("nijk,jk->nij", reg.reshape(n, 6, nj, 6), self.constants.subspace)   # (n, 6, nv)
            tau = self.constants.tau
            for k, iv, c, w in ms.compliance_cols:          # d q_link / d c = -tau_g
                parts.add(slice(c, c + 1), -w * (Jq[:, :, iv] * tau[samples, k][:, None])[:, :, None])
            for k, iv, c, w in ms.backlash_cols:            # d q_link / d b = d
                parts.add(slice(c, c + 1), w * (Jq[:, :, iv] * self.directions[samples, k][:, None])[:, :, None])
        if fid in ms.P_frame:                  # constant columns, the frame's own only, seen from the joint
            cols = ms.layout.frame_columns[fid]
            parts.add(cols, (model.frames[fid].placement.toActionMatrix() @ ms.P_frame[fid])[:, cols])
        if ms.has_base_params:                 # the base's own columns only
            cols = ms.layout.base_columns
            P = ms.P_base[:, cols]         # a stack times one matrix as one GEMM
            kept = self.derived(model.frames[fid].parentJoint, reg) if model.frames[fid].parentJoint else {}
            if "base" not in kept:
                kept["base"] = adjoint_inverse(Ri, pi).reshape(-1, 6)
            parts.add(cols, (kept["base"] @ P).reshape(n, 6, P.shape[1]))
        return parts


def supporting_columns(model, jid: int) -> np.ndarray:
    """Columns of a (6, 6 n_joints) kinematic regressor of joint jid that can be non-zero: its supports'."""
    return (6 * (np.asarray(model.supports[jid][1:], dtype=int)[:, None] - 1) + np.arange(6)).ravel()


def gemm_blocks(model, ms, jid: int) -> GemmBlocks | None:
    """Which free columns each joint supporting jid reaches through the twist map (its placement's, a
    calibrated fixed link's above it, its offset's), from the layout: value-independent. None when two
    joints share a column (ties across joints): the GEMM then runs over the whole map."""
    rows, cols, seen = [], [], np.zeros(ms.n_free, dtype=bool)
    for k, j in enumerate(model.supports[jid][1:]):
        reach = np.union1d(ms.layout.joint_columns.get(j, np.zeros(0, dtype=int)),
                           np.flatnonzero(ms.P_offset[model.joints[j].idx_v]))
        if len(reach) == 0:
            continue
        if seen[reach].any():
            return None
        seen[reach] = True
        rows.append(slice(6 * k, 6 * k + 6))
        cols.append(contiguous(reach))
    return GemmBlocks(rows, cols, np.flatnonzero(~seen))
