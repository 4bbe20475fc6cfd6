"""The robot at one parameter vector, and its kinematic state at each sample.

`ModelState` applies a `ParameterSet` to a copy of the nominal model. `SampleState` is one sample's
joint readings with forward kinematics run; it answers, for any frame, the pose in the measurement
frame and how that pose moves (a LOCAL right twist: M <- M exp6(xi)) with every free parameter and
with every read joint. Residuals only ever see this interface, which is what lets one residual serve
serial and closed-chain robots alike.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from .parameters import COMPONENTS, ParameterSet
from .robot import ConfigurationMap

LOCAL = pin.ReferenceFrame.LOCAL


def _exp6(v: np.ndarray) -> pin.SE3:
    return pin.exp6(pin.Motion(np.asarray(v, dtype=float)))


class ModelState:
    """A calibrated copy of the robot's model for the current parameter values.

    joint_names: the joints whose readings each sample provides (in that order).
    """

    def __init__(self, robot, params: ParameterSet, joint_names: list[str]):
        self.robot, self.params, self.joint_names = robot, params, list(joint_names)
        nominal = robot.model
        self.model = nominal.copy()
        self.data = self.model.createData()
        free = params.free_names
        self.n_free = len(free)
        col = params.column_map()   # parameter -> [(free column, coefficient)]; ties act on their leaders
        nj = nominal.njoints - 1
        # Maps from "twist of a placement" / "joint velocity" to the free-parameter vector.
        self.P_joint = np.zeros((6 * nj, self.n_free))
        self.offsets = np.zeros(len(self.joint_names))
        self.compliance = np.zeros(len(self.joint_names))
        self.compliance_cols: list[tuple] = []   # (read index, v index, free column, coefficient)
        self.P_offset = np.zeros((self.model.nv, self.n_free))
        self.P_frame: dict[int, np.ndarray] = {}
        self.P_base = np.zeros((6, self.n_free))
        self.base = robot_base = robot.base_placement
        read_v = {}
        for k, name in enumerate(self.joint_names):
            read_v[name] = (k, self.model.joints[robot.joint_id(name)].idx_v)
        self._read_v_index = np.array([read_v[n][1] for n in self.joint_names], dtype=int)
        groups: dict[tuple[str, str], None] = {}
        for p in params:
            if p.kind in ("joint_placement", "frame_placement", "base"):
                groups[(p.kind, p.target)] = None
            elif p.kind in ("joint_compliance", "joint_offset"):
                if p.target not in read_v:
                    raise ValueError(f"{p.kind.split('_')[1]} parameter {p.name}: joint '{p.target}' is not read "
                                     "by the data")
                k, iv = read_v[p.target]
                if p.kind == "joint_offset":
                    self.offsets[k] = p.value
                    for c, w in col.get(p.name, []):
                        self.P_offset[iv, c] += w
                else:
                    self.compliance[k] = p.value
                    self.compliance_cols += [(k, iv, c, w) for c, w in col.get(p.name, [])]
        induced = []   # joints that hang below a calibrated frame: (joint id, moved frame, its block)
        # frames first: a joint below a calibrated frame gets that change before its own placement error
        for kind, target in sorted(groups, key=lambda g: g[0] != "frame_placement"):
            delta = params.placement_vector(kind, target)
            Jr = pin.Jexp6(pin.Motion(delta))
            block = np.zeros((6, self.n_free))
            for c, comp in enumerate(COMPONENTS):
                for j, w in col.get(f"{target}.{comp}", []):
                    block[:, j] += w * Jr[:, c]
            if kind == "joint_placement":
                jid = robot.joint_id(target)
                self.model.jointPlacements[jid] = self.model.jointPlacements[jid] * _exp6(delta)
                self.P_joint[6 * (jid - 1):6 * jid] += block
            elif kind == "frame_placement":
                fid = robot.frame_id(target)
                moved = nominal.frames[fid].placement * _exp6(delta)
                for gid, rel in robot.frames_moved_with(fid):
                    self.model.frames[gid].placement = moved * rel
                    self.P_frame[gid] = self.P_frame.get(gid, 0.0) + rel.inverse().toActionMatrix() @ block
                for jid, rel in robot.joints_moved_with(fid):
                    self.model.jointPlacements[jid] = moved * rel
                    induced.append((jid, moved, block))
            else:
                self.base = robot_base * _exp6(delta)
                self.P_base = block
        for jid, moved, block in induced:
            final = self.model.jointPlacements[jid]
            self.P_joint[6 * (jid - 1):6 * jid] += (final.inverse() * moved).toActionMatrix() @ block
        self._owner: SampleState | None = None
        self.has_joint_params, self.has_base_params = bool(self.P_joint.any()), bool(self.P_base.any())
        self._qmap = ConfigurationMap(robot, self.joint_names)
        if self.compliance.any() or self.compliance_cols:
            self._gdata = nominal.createData()
        self.loops = robot.loops
        self.warm_starts: dict = {}      # sample label -> last assembled q (shared across parameter updates)
        if self.loops is not None:
            missing = [j for j in self.loops.actuated if j not in self.joint_names]
            if missing:
                raise ValueError(f"the data must read the actuated joints; missing: {', '.join(missing)}")
            self._act_order = [self.joint_names.index(j) for j in self.loops.actuated]
            self._adata = self.model.createData()

    def sample(self, values: np.ndarray, q_guess: np.ndarray | None = None, label=None) -> "SampleState":
        """State at one sample's joint readings (in `joint_names` order, SI units).

        On a closed-chain robot the passive joints are solved so that every loop closes (warm-started
        from `q_guess`, else from this sample's last solution); AssemblyError names `label` if impossible.
        """
        return SampleState(self, np.asarray(values, dtype=float), label, q_guess)

    def gravity_torque(self, values: np.ndarray) -> np.ndarray:
        """(n_read,) gravity torque of the nominal model at the readings (the compliance load)."""
        if not hasattr(self, "_gdata"):
            return np.zeros(len(self.joint_names))
        tau = pin.computeGeneralizedGravity(self.robot.model, self._gdata, self._qmap(values))
        return tau[self._read_v_index]

    def configuration(self, values: np.ndarray, q_guess: np.ndarray | None = None, label=None,
                      tau: np.ndarray | None = None) -> np.ndarray:
        if tau is not None:
            values = values - self.compliance * tau
        q = self._qmap(values + self.offsets)
        if self.loops is None:
            return q
        from .loops import assemble   # loops imports robot; keep the import graph one-way at load time
        guess = q_guess if q_guess is not None else self.warm_starts.get(label)
        if guess is not None:
            guess = guess.copy()
        q = assemble(self.robot, self.model, (values + self.offsets)[self._act_order], q_guess=guess,
                     sample=label, data=self._adata)
        if label is not None:
            self.warm_starts[label] = q
        return q


class SampleState:
    """One sample: readings + forward kinematics, with cached frame quantities."""

    def __init__(self, ms: ModelState, values: np.ndarray, label=None, q_guess=None):
        self.ms, self.values, self.label = ms, values, label
        self.tau = ms.gravity_torque(values) if hasattr(ms, "_gdata") else None
        self.q = ms.configuration(values, q_guess, label, self.tau)
        self._cache: dict[int, tuple] = {}
        self._implicit = None

    def _activate(self):
        ms = self.ms
        if ms._owner is not self:
            pin.computeJointJacobians(ms.model, ms.data, self.q)
            ms._owner = self

    def _frame(self, frame) -> tuple:
        fid = frame if isinstance(frame, int) else self.ms.robot.frame_id(frame)
        hit = self._cache.get(fid)
        if hit is None:
            self._activate()
            ms = self.ms
            oMf = pin.updateFramePlacement(ms.model, ms.data, fid).copy()
            Jq = pin.getFrameJacobian(ms.model, ms.data, fid, LOCAL).reshape(6, -1).copy()
            hit = [ms.base * oMf, oMf, Jq, None]
            self._cache[fid] = hit
        return hit

    def pose(self, frame) -> pin.SE3:
        """World (measurement-frame) pose of a frame."""
        return self._frame(frame)[0]

    def frame_joint_jacobian(self, frame) -> np.ndarray:
        """(6, n_read) LOCAL twist of the frame per unit of each read joint (loops closed).

        The gravity load's own change with the readings (compliance x d tau_g / dq, a second-order term)
        is left out."""
        Jq = self._frame(frame)[2]
        J = Jq[:, self.ms._read_v_index]
        if self.ms.loops is not None:
            J = J + Jq[:, self.ms.loops.passive_v] @ self._passive_sensitivity()[1]
        return J

    def frame_parameter_jacobian(self, frame) -> np.ndarray:
        """(6, n_free) LOCAL twist of the frame per unit of each free parameter (loops closed)."""
        hit = self._frame(frame)
        if hit[3] is None:
            J = self._tree_parameter_jacobian(frame, hit)
            if self.ms.loops is not None:
                J = J + hit[2][:, self.ms.loops.passive_v] @ self._passive_sensitivity()[0]
            hit[3] = J
        return hit[3]

    def _tree_parameter_jacobian(self, frame, hit) -> np.ndarray:
        """Parameter Jacobian with every joint held at its current value (the spanning tree's view)."""
        if len(hit) == 4:
            ms = self.ms
            fid = frame if isinstance(frame, int) else ms.robot.frame_id(frame)
            self._activate()
            J = hit[2] @ ms.P_offset
            for k, iv, c, w in ms.compliance_cols:          # d q_link / d c = -tau_g
                J[:, c] -= w * hit[2][:, iv] * self.tau[k]
            if ms.has_joint_params:
                reg = pin.computeFrameKinematicRegressor(ms.model, ms.data, fid, LOCAL)
                J += reg @ ms.P_joint
            if fid in ms.P_frame:
                J += ms.P_frame[fid]
            if ms.has_base_params:
                J += hit[1].inverse().toActionMatrix() @ ms.P_base
            hit.append(J)
        return hit[4]

    def _passive_sensitivity(self) -> tuple[np.ndarray, np.ndarray]:
        """(dq_passive/dtheta, dq_passive/dq_read) from the implicit-function theorem on the closures:
        c(q_p, q_a, theta) = 0  =>  dq_p = -C_p^+ (C_theta dtheta + C_a dq_a)."""
        if self._implicit is None:
            ms, L = self.ms, self.ms.loops
            _, dc_dv = L.constraint_jacobian(ms.model, ms._adata, self.q)
            hits1 = [self._frame(c.frame1) for c in L.closures]
            hits2 = [self._frame(c.frame2) for c in L.closures]
            _, D1, D2 = L.closure_error([h[1] for h in hits1], [h[1] for h in hits2])
            C_theta = np.vstack([d1 @ self._tree_parameter_jacobian(c.frame1, h1)
                                 + d2 @ self._tree_parameter_jacobian(c.frame2, h2)
                                 for c, d1, d2, h1, h2 in zip(L.closures, D1, D2, hits1, hits2)])
            rhs = np.hstack([C_theta, dc_dv[:, ms._read_v_index]])
            sol = -np.linalg.lstsq(dc_dv[:, L.passive_v], rhs, rcond=None)[0]
            self._implicit = (sol[:, :ms.n_free], sol[:, ms.n_free:])
        return self._implicit
