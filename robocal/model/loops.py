"""A closed chain's loops: the closures, the actuated/passive split, and assembly.

A closed chain is its URDF spanning tree (loaded by Pinocchio) plus closure elements that URDF readers
ignore (read by robocal.model.loops_urdf). `LoopSet` stacks the closures' constraint rows
(robocal.model.loop_rows) and the joint relations' rows (couplings, screw transmissions: one linear row
each, robocal.model.joint_relations); `assemble` solves the passive joints for given actuated readings
(closed-chain forward kinematics) with the damped Newton of robocal.model.inverse_kinematics.
Each closure k is anchored on two Pinocchio frames ``<name>.link1`` and ``<name>.link2`` added to
``robot.model``; moving a loop anchor is therefore a frame-placement edit.
"""
from __future__ import annotations

import copy
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from robocal.errors import AssemblyError, InputError
from robocal.model.inverse_kinematics import damped_newton
from robocal.model.joint_relations import Coupling
from robocal.model.loop_rows import Closure, closure_rows


class JointSlot(NamedTuple):
    """Where a one-dof joint sits in q and v (nq 2: a continuous joint stored as cos, sin)."""
    idx_q: int
    idx_v: int
    nq: int


class LoopSet:
    """The closures and the actuated/passive split of a closed-chain robot.

    closures   list of Closure
    relations  joint relations (Coupling, ScrewTransmission): one row each, enforced by `assemble`
    actuated   names of the joints read by encoders (1-dof joints), in the readings' order
    driven     the actuated joints whose reading acts through a relation (screw strokes): solved
    passive    names of the other joints with degrees of freedom
    n_rows     number of closure rows (n_relation_rows: relation rows)
    actuated_v, passive_v   index arrays into the velocity vector (nv,)
    solved_v   what assembly solves: passive_v plus the driven joints
    """

    def __init__(self, model: pin.Model, closures: list[Closure], actuated: list[str],
                 relations: list | None = None):
        self.closures = list(closures)
        self.relations = list(relations or [])
        self.actuated = list(actuated)
        self.driven = [r.driven for r in self.relations if r.driven is not None]
        stray = [j for j in self.driven if j not in self.actuated]
        if stray:
            raise InputError(f"joint '{stray[0]}' is driven by a transmission but not listed in <actuated>",
                             field="actuated")
        self.n_relation_rows = len(self.relations)
        self.nv = model.nv
        self.n_rows = int(sum(c.rows for c in self.closures))
        self._ids = [(model.getFrameId(c.frame1), model.getFrameId(c.frame2)) for c in self.closures]
        self._slices = []
        start = 0
        for c in self.closures:
            self._slices.append(slice(start, start + c.rows))
            start += c.rows
        points = [k for k, c in enumerate(self.closures) if c.kind == "point"]
        self._other = [k for k, c in enumerate(self.closures) if c.kind != "point"]
        self._point_ids1 = [self._ids[k][0] for k in points]
        self._point_ids2 = [self._ids[k][1] for k in points]
        self._point_rows = np.array([r for k in points for r in range(self._slices[k].start, self._slices[k].stop)],
                                    dtype=int)
        names = [model.names[j] for j in range(1, model.njoints) if model.joints[j].nv > 0]
        self.passive = [n for n in names if n not in self.actuated]
        # index slots, not Pinocchio JointModels: those do not pickle, and a robot must (Dask workers)
        self._act_joints = [JointSlot(j.idx_q, j.idx_v, j.nq)
                            for j in (model.joints[model.getJointId(n)] for n in self.actuated)]
        self.actuated_v = np.array([j.idx_v for j in self._act_joints], dtype=int)
        self.passive_v = np.concatenate(
            [np.arange(model.joints[model.getJointId(n)].idx_v,
                       model.joints[model.getJointId(n)].idx_v + model.joints[model.getJointId(n)].nv)
             for n in self.passive]).astype(int) if self.passive else np.zeros(0, dtype=int)
        driven_v = [j.idx_v for n, j in zip(self.actuated, self._act_joints) if n in self.driven]
        self.solved_v = np.sort(np.concatenate([self.passive_v, np.array(driven_v, dtype=int)]))
        self._set = [k for k, n in enumerate(self.actuated) if n not in self.driven]

        def where(name):
            j = model.joints[model.getJointId(name)]
            return j.idx_q, j.idx_v, j.nq
        self._rel_index = [([where(n) for n in r.joints],
                            self.actuated.index(r.driven) if r.driven is not None else None)
                           for r in self.relations]

    @property
    def couplings(self) -> list[Coupling]:
        return [r for r in self.relations if r.kind == "coupling"]

    def with_relations(self, relations: list) -> "LoopSet":
        """A copy with other relation values (same joints, e.g. a calibrated lead)."""
        out = copy.copy(self)
        out.relations = list(relations)
        return out

    # ---- joint relations -----------------------------------------------------------------
    @staticmethod
    def _joint_value(q, where) -> float:
        iq, _, nq = where
        return q[iq] if nq == 1 else np.arctan2(q[iq + 1], q[iq])

    def relation_reading(self, k: int) -> int | None:
        """Index in `actuated` of the reading that drives relation k, or None."""
        return self._rel_index[k][1]

    def relation_values(self, q: np.ndarray, k: int) -> tuple[float, float]:
        """The two joint values that relation k ties, at q."""
        return tuple(self._joint_value(q, w) for w in self._rel_index[k][0])

    def relation_rows(self, q: np.ndarray, readings=None, with_readings: bool = True):
        """Relation rows c (n_rel,) and dc/dv (n_rel, nv) at q; `readings` in `actuated` order.

        with_readings=False keeps only the rows that involve no reading (for inverse kinematics,
        where the driven readings are outputs)."""
        keep = [k for k, (_, act) in enumerate(self._rel_index) if with_readings or act is None]
        c = np.empty(len(keep))
        jac = np.zeros((len(keep), self.nv))
        for row, k in enumerate(keep):
            rel, (idx, act) = self.relations[k], self._rel_index[k]
            a = rel.coefficients()
            c[row] = sum(ai * self._joint_value(q, w) for ai, w in zip(a, idx))
            if act is not None:
                c[row] -= rel.reading_scale * readings[act]
            for ai, w in zip(a, idx):
                jac[row, w[1]] += ai
        return c, jac

    def _drive(self, q: np.ndarray, values: np.ndarray) -> None:
        """Put each driven joint where its relation holds at the current value of its partner."""
        for rel, (idx, act) in zip(self.relations, self._rel_index):
            if act is not None:
                a = rel.coefficients()
                q[idx[0][0]] = (rel.reading_scale * values[act] - a[1] * self._joint_value(q, idx[1])) / a[0]

    # ---- configurations ------------------------------------------------------------------
    def set_actuated(self, q: np.ndarray, values) -> np.ndarray:
        """Copy of q (nq,) with the actuated joints at `values` (n_act,), SI (m or rad)."""
        values = np.asarray(values, dtype=float).reshape(-1)
        if values.size != len(self.actuated):
            raise InputError(f"expected {len(self.actuated)} actuated readings "
                             f"({', '.join(self.actuated)}), got {values.size}", field="actuated")
        q = np.array(q, dtype=float)
        for k in self._set:
            j, value = self._act_joints[k], values[k]
            if j.nq == 1:
                q[j.idx_q] = value
            else:  # continuous joint stored as (cos, sin)
                q[j.idx_q], q[j.idx_q + 1] = np.cos(value), np.sin(value)
        self._drive(q, values)
        return q

    def actuated_values(self, q: np.ndarray) -> np.ndarray:
        """Readings (n_act,) of the actuated joints in configuration q (driven ones through their relation)."""
        out = np.empty(len(self._act_joints))
        for k, j in enumerate(self._act_joints):
            out[k] = q[j.idx_q] if j.nq == 1 else np.arctan2(q[j.idx_q + 1], q[j.idx_q])
        for rel, (idx, act) in zip(self.relations, self._rel_index):
            if act is not None:
                a = rel.coefficients()
                out[act] = sum(ai * self._joint_value(q, w) for ai, w in zip(a, idx)) / rel.reading_scale
        return out

    # ---- constraint rows -----------------------------------------------------------------
    def closure_error(self, poses1, poses2):
        """Stacked constraint vector and its derivatives w.r.t. each anchor frame.

        poses1[k], poses2[k]: world SE3 of closure k's two frames.
        Returns c (n_rows,), D1 and D2: lists with D1[k], D2[k] of shape (rows_k, 6), the derivative
        of closure k's rows w.r.t. a LOCAL right twist [v; w] of its frame 1 / frame 2.
        """
        c = np.empty(self.n_rows)
        D1, D2 = [], []
        for closure, sl, M1, M2 in zip(self.closures, self._slices, poses1, poses2):
            ck, d1, d2 = closure_rows(closure, M1, M2)
            c[sl] = ck
            D1.append(d1)
            D2.append(d2)
        return c, D1, D2

    def constraint_jacobian(self, model: pin.Model, data: pin.Data, q: np.ndarray):
        """c (n_rows,) and dc/dv (n_rows, model.nv) at q, for q <- integrate(q, v).

        Runs computeJointJacobians and updateFramePlacements on `data`.
        """
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        c = np.empty(self.n_rows)
        jac = np.empty((self.n_rows, model.nv))
        local = pin.ReferenceFrame.LOCAL
        oMf = data.oMf
        if self._point_rows.size:  # point closures (the common case) in one batch:
            # rows = [-I, [c]x] J1 + [R12, 0] J2, numpy calls shared by all of them
            h1 = np.array([oMf[i].homogeneous for i in self._point_ids1])
            h2 = np.array([oMf[i].homogeneous for i in self._point_ids2])
            j1 = np.array([pin.getFrameJacobian(model, data, i, local) for i in self._point_ids1])
            j2 = np.array([pin.getFrameJacobian(model, data, i, local) for i in self._point_ids2])
            r1t = np.swapaxes(h1[:, :3, :3], 1, 2)
            cp = r1t @ (h2[:, :3, 3:] - h1[:, :3, 3:])  # (k, 3, 1)
            w = j1[:, 3:]
            x, y, z = cp[:, 0], cp[:, 1], cp[:, 2]
            cross = np.stack([y * w[:, 2] - z * w[:, 1], z * w[:, 0] - x * w[:, 2], x * w[:, 1] - y * w[:, 0]], 1)
            c[self._point_rows] = cp.reshape(-1)
            jac[self._point_rows] = (cross - j1[:, :3] + (r1t @ h2[:, :3, :3]) @ j2[:, :3]).reshape(-1, model.nv)
        for k in self._other:
            closure, sl, (i1, i2) = self.closures[k], self._slices[k], self._ids[k]
            ck, d1, d2 = closure_rows(closure, oMf[i1], oMf[i2])
            c[sl] = ck
            jac[sl] = (d1 @ pin.getFrameJacobian(model, data, i1, local).reshape(6, -1)
                       + d2 @ pin.getFrameJacobian(model, data, i2, local).reshape(6, -1))
        return c, jac

    def constraint_error(self, model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
        """c (n_rows,) at q (forward kinematics only, no Jacobians)."""
        pin.framesForwardKinematics(model, data, q)
        return self.closure_error([data.oMf[i] for i, _ in self._ids],
                                  [data.oMf[i] for _, i in self._ids])[0]


def _loops_of(robot):
    if robot.loops is None:
        raise InputError(f"robot '{robot.name}' has no loop closures")
    return robot.loops


def assemble(robot, model: pin.Model, actuated_values, q_guess=None, sample=None, tol: float = 1e-12,
             max_iter: int = 50, data: pin.Data | None = None, singular_rcond: float = 1e-5,
             loops: LoopSet | None = None) -> np.ndarray:
    """Closed-chain forward kinematics: solve the passive joints for given actuated readings.

    robot           Robot whose `loops` describe the closures
    model           the model to use (robot.model or a calibrated copy with edited placements)
    actuated_values (n_act,) readings in the order of robot.loops.actuated (m or rad)
    q_guess         (nq,) warm start (e.g. the previous sample's solution); neutral by default
    sample          label used in the error message
    loops           the LoopSet to use (default robot.loops; a calibrated copy carries fitted relations)
    Returns q (nq,) with the actuated joints at the readings and every closure and joint relation
    satisfied (max |c| < tol). Raises AssemblyError when there is no assembly or it is singular.
    """
    loops = _loops_of(robot) if loops is None else loops
    data = model.createData() if data is None else data
    q0 = pin.neutral(model) if q_guess is None else np.asarray(q_guess, dtype=float)
    values = np.asarray(actuated_values, dtype=float).reshape(-1)
    q0 = loops.set_actuated(q0, values)
    if not loops.relations:
        rows = lambda q: loops.constraint_jacobian(model, data, q)  # noqa: E731
    else:
        def rows(q):
            c, jac = loops.constraint_jacobian(model, data, q)
            cr, jr = loops.relation_rows(q, values)
            return np.concatenate([c, cr]), np.vstack([jac, jr])
    return damped_newton(rows, q0, lambda q, v: pin.integrate(model, q, v), free=loops.solved_v, tol=tol,
                         max_iterations=max_iter, singular_rcond=singular_rcond, sample=sample,
                         what="closed-chain assembly", failure=AssemblyError)


