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

from robocal.model.joint_tilt import JointTilts
from robocal.model.loops import assemble
from robocal.model.parameters import ParameterSet
from robocal.model.state_layout import state_layout

LOCAL = pin.ReferenceFrame.LOCAL


def joint_key(robot, layout, deltas: np.ndarray) -> tuple:
    """What the calibrated model's joint placements depend on, whatever the parameter structure: the robot and,
    for each group that moves a joint and is away from zero (exp6(0) is exactly the identity), its id, kind and
    six values. Equal keys: equal placements (the batched path keeps its regressors on it)."""
    moving = deltas[layout.joint_group_rows]
    return robot, np.concatenate((layout.joint_group_ids, moving), axis=1)[np.any(moving != 0.0, axis=1)]


class ModelState:
    """A calibrated copy of the robot's model for the current parameter values.

    joint_names: the joints whose readings each sample provides (in that order).
    """

    def __init__(self, robot, params: ParameterSet, joint_names: list[str]):
        self.robot, self.params, self.joint_names = robot, params, list(joint_names)
        layout = state_layout(robot, params, self.joint_names)    # the structure, worked out once
        self.layout = layout
        nominal = robot.model
        self._data = None
        self.n_free = layout.n_free
        values = layout.values(params)
        deltas = np.append(values, 0.0)[layout.group_value_index]     # (groups, 6); a missing component: 0
        # exp6(0) is exactly the identity: with no frame group and every joint placement at nominal (a fit's
        # start, a registration) the calibrated model is the nominal one, shared (nothing below writes to it)
        moved = layout.has_frame_groups or bool(np.any(deltas[layout.joint_placement_rows]))
        self.model = nominal.copy() if moved else nominal
        n_read = len(self.joint_names)
        nj = nominal.njoints - 1
        # Maps from "twist of a placement" / "joint velocity" to the free-parameter vector.
        self.P_joint = np.zeros((6 * nj, self.n_free))
        self.offsets = layout.read_values("joint_offset", values, n_read)
        self.compliance = layout.read_values("joint_compliance", values, n_read)
        self.backlash = layout.read_values("joint_backlash", values, n_read)
        # shared with the layout unless a closed chain's relations rewrite them (_setup_relations)
        self.P_offset, self.compliance_cols, self.backlash_cols = (layout.P_offset, layout.compliance_cols,
                                                                   layout.backlash_cols)
        self.P_frame: dict[int, np.ndarray] = {}
        self.P_base = np.zeros((6, self.n_free))
        self.base = robot_base = robot.base_placement
        self._read_v_index = layout.read_v_index
        tilts = [(jid, values[slot], cols) for jid, slot, cols in layout.tilts]
        induced = []   # joints that hang below a calibrated frame: (joint id, moved frame, its block)
        frame_blocks = []
        self._deltas, self._joint_key = deltas, None
        for group, delta in zip(layout.groups, deltas):    # frames first, parents before children (state_layout)
            kind = group.kind
            if kind == "joint_placement" and not moved:     # Jexp6(0) is exactly the identity too
                self.P_joint[6 * (group.index - 1):6 * group.index] += group.selector
                continue
            twist = delta             # exp6 and Jexp6 take the 6-vector itself (no Motion: ten times faster)
            block = pin.Jexp6(twist) @ group.selector
            if kind == "joint_placement":
                jid = group.index
                self.model.jointPlacements[jid] = self.model.jointPlacements[jid] * pin.exp6(twist)
                self.P_joint[6 * (jid - 1):6 * jid] += block
            elif kind == "frame_placement":
                fid = group.index
                frame_moved = self.model.frames[fid].placement * pin.exp6(twist)
                moved_with = robot.frames_moved_with(fid)
                for gid, rel in moved_with:
                    self.model.frames[gid].placement = frame_moved * rel
                frame_blocks.append((fid, block, [gid for gid, _ in moved_with]))
                for jid, rel in robot.joints_moved_with(fid):
                    self.model.jointPlacements[jid] = frame_moved * rel
                    induced.append((jid, frame_moved, block))
            else:
                self.base = robot_base * pin.exp6(twist)
                self.P_base = block
        for fid, block, moved_with in frame_blocks:   # every placement final: frames below carry the twist
            final = self.model.frames[fid].placement
            for gid in moved_with:
                rel = self.model.frames[gid].placement.inverse() * final
                self.P_frame[gid] = self.P_frame.get(gid, 0.0) + rel.toActionMatrix() @ block
        for jid, frame_moved, block in induced:
            final = self.model.jointPlacements[jid]
            self.P_joint[6 * (jid - 1):6 * jid] += (final.inverse() * frame_moved).toActionMatrix() @ block
        self._owner: SampleState | None = None
        self.has_joint_params, self.has_base_params = layout.has_joint_params, layout.has_base_params
        self._qmap = layout.qmap
        if self.compliance.any() or self.compliance_cols:
            self._gdata = nominal.createData()
        # the model the samples run: the calibrated one, or a copy whose tilted joints move per sample (made on
        # first use: a batched pass runs its own, robocal.model.batch_kinematics)
        self.tilts = JointTilts(robot, self.model, tilts) if tilts else None
        self._kin_model, self._kin_data = (None, None) if tilts else (self.model, None)
        self.loops = robot.loops
        self.warm_starts: dict = {}      # sample label -> last assembled q (shared across parameter updates)
        if self.loops is not None:
            missing = [j for j in self.loops.actuated if j not in self.joint_names]
            if missing:
                raise ValueError(f"the data must read the actuated joints; missing: {', '.join(missing)}")
            self._act_order = [self.joint_names.index(j) for j in self.loops.actuated]
            self._adata = self.model.createData()
            self._setup_relations(params, layout.columns)
        elif layout.has_transmission:
            raise ValueError("transmission parameters need a robot with joint relations (screw transmissions or "
                             "couplings)")

    @property
    def joint_key(self) -> tuple:
        """What this model's joint placements depend on (see `joint_key`), worked out on first use."""
        if self._joint_key is None:
            self._joint_key = joint_key(self.robot, self.layout, self._deltas)
        return self._joint_key

    @property
    def data(self) -> pin.Data:
        """The calibrated model's Data, made on first use (a batched pass never needs it)."""
        if self._data is None:
            self._data = self.model.createData()
        return self._data

    @property
    def kin_model(self) -> pin.Model:
        """The model the samples run: the calibrated one, or (tilts) a copy whose tilted joints move per sample."""
        if self._kin_model is None:
            self._kin_model = self.model.copy()
            self._kin_data = self._kin_model.createData()
        return self._kin_model

    @property
    def kin_data(self) -> pin.Data:
        if self.tilts is None:
            return self.data
        self.kin_model            # made with its Data on first use
        return self._kin_data

    def _setup_relations(self, params: ParameterSet, col: dict) -> None:
        """Joint relations (screw transmissions, couplings) of a closed chain, and their parameters.

        A read joint driven through a relation (a screw's stroke) is solved by assembly, so whatever
        shifts its reading (offset, compliance, backlash) acts through the relation row, not on the tree
        joint: those columns move from the tree Jacobian to `driven_cols`."""
        loops = self.loops
        index = {r.name: k for k, r in enumerate(loops.relations)}
        relations = list(loops.relations)
        self.relation_cols = []     # (relation index, component, free column, coefficient)
        for p in params:
            if p.kind != "transmission":
                continue
            k = index.get(p.target)
            if k is None:
                raise ValueError(f"transmission parameter {p.name}: the robot has no joint relation '{p.target}'")
            component = p.name.rsplit(".", 1)[-1]
            if component not in relations[k].components:
                raise ValueError(f"transmission parameter {p.name}: '{component}' is not one of "
                                 f"{', '.join(relations[k].components)}")
            relations[k] = relations[k].with_value(component, p.value)
            self.relation_cols += [(k, component, c, w) for c, w in col.get(p.name, [])]
        if relations != loops.relations:
            self.loops = loops.with_relations(relations)
        self.driven_reads = [self.joint_names.index(j) for j in loops.driven]
        self.P_offset = self.P_offset.copy()          # rewritten below: not the layout's
        self.compliance_cols, self.backlash_cols = list(self.compliance_cols), list(self.backlash_cols)
        self.driven_cols = []       # (read index, free column, coefficient, 'offset' | 'compliance' | 'backlash')
        for k in self.driven_reads:
            iv = self._read_v_index[k]
            self.driven_cols += [(k, c, self.P_offset[iv, c], "offset") for c in np.flatnonzero(self.P_offset[iv])]
            self.P_offset[iv] = 0.0
        for name in ("compliance", "backlash"):
            cols = getattr(self, f"{name}_cols")
            self.driven_cols += [(k, c, w, name) for k, iv, c, w in cols if k in self.driven_reads]
            cols[:] = [e for e in cols if e[0] not in self.driven_reads]

    @property
    def actuated_order(self) -> list[int]:
        """Closed chains: the index in `joint_names` of each actuated joint, in robot.loops.actuated order."""
        return self._act_order

    @property
    def read_v_index(self) -> np.ndarray:
        """Velocity index of each read joint, in `joint_names` order."""
        return self._read_v_index

    @property
    def needs_gravity(self) -> bool:
        """Whether the samples need their gravity torque (compliance parameters set or free)."""
        return hasattr(self, "_gdata")

    def link_readings(self, values: np.ndarray, tau: np.ndarray | None = None) -> np.ndarray:
        """What the joints are set to: readings + offsets - compliance * gravity torque."""
        values = values + self.offsets
        return values if tau is None else values - self.compliance * tau

    def sample(self, values: np.ndarray, q_guess: np.ndarray | None = None, label=None,
               direction: np.ndarray | None = None) -> "SampleState":
        """State at one sample's joint readings (in `joint_names` order, SI units).

        direction: each read joint's approach direction (-1, 0, +1) for the backlash parameters; None = 0.

        On a closed-chain robot the passive joints are solved so that every loop closes (warm-started
        from `q_guess`, else from this sample's last solution); AssemblyError names `label` if impossible.
        """
        return SampleState(self, np.asarray(values, dtype=float), label, q_guess, direction)

    def gravity_torque(self, values: np.ndarray) -> np.ndarray:
        """(n_read,) gravity torque of the nominal model at the readings (the compliance load)."""
        if not hasattr(self, "_gdata"):
            return np.zeros(len(self.joint_names))
        tau = pin.computeGeneralizedGravity(self.robot.model, self._gdata, self._qmap(values))
        return tau[self._read_v_index]

    def configuration(self, values: np.ndarray, q_guess: np.ndarray | None = None, label=None,
                      tau: np.ndarray | None = None) -> np.ndarray:
        values = self.link_readings(values, tau)
        q = self._qmap(values)
        if self.loops is None:
            return q
        guess = q_guess if q_guess is not None else self.warm_starts.get(label)
        if guess is not None:
            guess = guess.copy()
        q = assemble(self.robot, self.model, values[self._act_order], q_guess=guess, sample=label, data=self._adata,
                     loops=self.loops)
        if label is not None:
            self.warm_starts[label] = q
        return q


class SampleState:
    """One sample: readings + forward kinematics, with cached frame quantities."""

    def __init__(self, ms: ModelState, values: np.ndarray, label=None, q_guess=None, direction=None):
        self.ms, self.values, self.label = ms, values, label
        self.direction = np.zeros(len(values)) if direction is None else np.asarray(direction, dtype=float)
        self.tau = ms.gravity_torque(values) if hasattr(ms, "_gdata") else None
        self.moments = ms.tilts.moments(ms._qmap(values)) if ms.tilts else None
        # the link sits b on the approach side of the reading; the gravity load stays that of the reading
        self.q = ms.configuration(values + ms.backlash * self.direction, q_guess, label, self.tau)
        self._cache: dict[int, tuple] = {}
        self._implicit = None

    def _activate(self):
        ms = self.ms
        if ms._owner is not self:
            if ms.tilts:
                ms.tilts.apply(ms.kin_model, self.moments)
            pin.computeJointJacobians(ms.kin_model, ms.kin_data, self.q)
            ms._owner = self

    def _frame(self, frame) -> tuple:
        fid = frame if isinstance(frame, int) else self.ms.robot.frame_id(frame)
        hit = self._cache.get(fid)
        if hit is None:
            self._activate()
            ms = self.ms
            oMf = pin.updateFramePlacement(ms.kin_model, ms.kin_data, fid).copy()
            Jq = pin.getFrameJacobian(ms.kin_model, ms.kin_data, fid, LOCAL).reshape(6, -1).copy()
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
            if self.ms.driven_reads:          # solved by assembly: the reading acts through its relation
                J = J.copy()
                J[:, self.ms.driven_reads] = 0.0
            J = J + Jq[:, self.ms.loops.solved_v] @ self._passive_sensitivity()[1]
        return J

    def frame_parameter_jacobian(self, frame) -> np.ndarray:
        """(6, n_free) LOCAL twist of the frame per unit of each free parameter (loops closed)."""
        hit = self._frame(frame)
        if hit[3] is None:
            J = self._tree_parameter_jacobian(frame, hit)
            if self.ms.loops is not None:
                J = J + hit[2][:, self.ms.loops.solved_v] @ self._passive_sensitivity()[0]
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
            for k, iv, c, w in ms.backlash_cols:            # d q_link / d b = d
                J[:, c] += w * hit[2][:, iv] * self.direction[k]
            if ms.has_joint_params or ms.tilts:
                reg = pin.computeFrameKinematicRegressor(ms.kin_model, ms.kin_data, fid, LOCAL)
                J += reg @ ms.P_joint
                if ms.tilts:
                    J += ms.tilts.jacobian(reg, ms.P_joint, self.moments)
            if fid in ms.P_frame:
                J += ms.P_frame[fid]
            if ms.has_base_params:
                J += hit[1].inverse().toActionMatrix() @ ms.P_base
            hit.append(J)
        return hit[4]

    def _passive_sensitivity(self) -> tuple[np.ndarray, np.ndarray]:
        """(dq_solved/dtheta, dq_solved/dq_read) from the implicit-function theorem on the closures and
        joint relations: c(q_s, q_a, theta) = 0  =>  dq_s = -C_s^+ (C_theta dtheta + C_a dq_a)."""
        if self._implicit is None:
            ms, L = self.ms, self.ms.loops
            _, dc_dv = L.constraint_jacobian(ms.model, ms._adata, self.q)
            hits1 = [self._frame(c.frame1) for c in L.closures]
            hits2 = [self._frame(c.frame2) for c in L.closures]
            _, D1, D2 = L.closure_error([h[1] for h in hits1], [h[1] for h in hits2])
            C_theta = np.vstack([d1 @ self._tree_parameter_jacobian(c.frame1, h1)
                                 + d2 @ self._tree_parameter_jacobian(c.frame2, h2)
                                 for c, d1, d2, h1, h2 in zip(L.closures, D1, D2, hits1, hits2)]
                                + [np.zeros((0, ms.n_free))])
            C_read = dc_dv[:, ms._read_v_index]
            if L.relations:
                C_read[:, ms.driven_reads] = 0.0
                rel_theta, rel_read, jr = self._relation_sensitivity()
                dc_dv = np.vstack([dc_dv, jr])
                C_theta, C_read = np.vstack([C_theta, rel_theta]), np.vstack([C_read, rel_read])
            rhs = np.hstack([C_theta, C_read])
            sol = -np.linalg.lstsq(dc_dv[:, L.solved_v], rhs, rcond=None)[0]
            self._implicit = (sol[:, :ms.n_free], sol[:, ms.n_free:])
        return self._implicit

    def _relation_sensitivity(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Relation rows: d/dtheta (n_rel, n_free), d/dreadings (n_rel, n_read), d/dv (n_rel, nv)."""
        ms, L = self.ms, self.ms.loops
        u_read = ms.link_readings(self.values + ms.backlash * self.direction, self.tau)
        u = u_read[ms._act_order]
        _, jr = L.relation_rows(self.q, u)
        rel_read = jr[:, ms._read_v_index]
        rel_read[:, ms.driven_reads] = 0.0
        rel_theta = np.zeros((len(L.relations), ms.n_free))
        for k, component, c, w in ms.relation_cols:
            act = L.relation_reading(k)
            rel_theta[k, c] += w * L.relations[k].derivative(component, L.relation_values(self.q, k),
                                                             u[act] if act is not None else 0.0)
        factor = {"offset": lambda k: 1.0, "compliance": lambda k: -self.tau[k],
                  "backlash": lambda k: self.direction[k]}
        for k_rel, rel in enumerate(L.relations):
            act = L.relation_reading(k_rel)
            if act is None:
                continue
            k = ms._act_order[act]
            rel_read[k_rel, k] = -rel.reading_scale
            for kr, c, w, what in ms.driven_cols:
                if kr == k:
                    rel_theta[k_rel, c] -= rel.reading_scale * w * factor[what](kr)
        return rel_theta, rel_read, jr
