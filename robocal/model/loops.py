"""A closed chain's loops: the closures, the actuated/passive split, and assembly.

A closed chain is its spanning tree (loaded by Pinocchio) plus closures: read from robocal's URDF loop
elements (robocal.model.loops_urdf), from MJCF equality constraints (robocal.model.mjcf) or from Pinocchio
constraint models (robocal.model.constraint_models). `LoopSet` stacks the closures' constraint rows (point and
frame closures from Pinocchio's constraint kinematics, the other kinds from robocal.model.loop_rows:
robocal.model.pinocchio_rows) and the joint relations' rows (couplings, screw transmissions: one linear row
each, robocal.model.joint_relations); `assemble` solves the passive joints for given actuated readings
(closed-chain forward kinematics): Pinocchio-style projected Gauss-Newton steps while they lower the error
(robocal.model.projected_assembly, the faster at equal accuracy: benchmarks/closed_chain_assembly.py), the damped
Newton of robocal.model.inverse_kinematics from the same start otherwise.
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
from robocal.model.pinocchio_rows import PinocchioRows
from robocal.model.projected_assembly import projected_newton


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
        self._slices = []
        start = 0
        for c in self.closures:
            self._slices.append(slice(start, start + c.rows))
            start += c.rows
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

    def pinocchio_rows(self, model: pin.Model) -> PinocchioRows:
        """The closure rows of `model` (robot.model or a calibrated copy) through Pinocchio's constraint models,
        built on first use and kept for the last model asked about: anchor frames edited in place afterwards are
        not seen (robocal edits copies: ModelState)."""
        cached = self.__dict__.get("_pinocchio_rows")
        if cached is None or cached.model is not model:
            cached = self.__dict__["_pinocchio_rows"] = PinocchioRows(model, self.closures, self._slices, self.n_rows)
        return cached

    def __getstate__(self):     # Pinocchio's constraint models do not pickle (Dask workers): rebuilt on use
        state = dict(self.__dict__)
        state.pop("_pinocchio_rows", None)
        return state

    def constraint_jacobian(self, model: pin.Model, data: pin.Data, q: np.ndarray):
        """c (n_rows,) and dc/dv (n_rows, model.nv) at q, for q <- integrate(q, v): point and frame closures from
        Pinocchio's constraint models (robocal.model.pinocchio_rows), the other kinds from robocal's rows.

        Runs computeJointJacobians on `data`.
        """
        return self.pinocchio_rows(model).rows_and_jacobian(model, data, q)

    def constraint_error(self, model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
        """c (n_rows,) at q (forward kinematics only, no Jacobians)."""
        return self.pinocchio_rows(model).rows_only(model, data, q)

    def worst_closure(self, c: np.ndarray) -> tuple[str, float]:
        """(name, max |row|) of the closure whose rows are furthest from closed in the closure vector c."""
        errors = [float(np.abs(c[sl]).max()) if sl.stop > sl.start else 0.0 for sl in self._slices]
        k = int(np.argmax(errors))
        return self.closures[k].name, errors[k]


def loop_set(robot, closures: list[Closure], actuated: list[str], relations: list, source: str) -> LoopSet:
    """The LoopSet of a robot's closures and relations, its actuated joints checked (1-dof joints of the model,
    listed once, required with closures) and its rows counted against the passive degrees of freedom."""
    model = robot.model
    if closures and not actuated:
        raise InputError("a closed chain needs its actuated joints (the joints read by encoders)", source=source,
                         field="actuated")
    for n in actuated:
        if not model.existJointName(n):
            raise InputError(f"actuated joint '{n}' is not a joint of the model", source=source, field="actuated")
        if model.joints[model.getJointId(n)].nv != 1:
            raise InputError(f"actuated joint '{n}' must have one degree of freedom", source=source,
                             field="actuated")
    if len(set(actuated)) != len(actuated):
        raise InputError("an actuated joint is listed twice", source=source, field="actuated")
    try:
        loops = LoopSet(model, closures, actuated, relations)
    except InputError as exc:
        raise InputError(exc.reason, source=source, field=exc.field) from None
    n_rows = loops.n_rows + loops.n_relation_rows
    if closures and n_rows < loops.solved_v.size:
        raise InputError(f"the closures and joint relations give {n_rows} constraint rows for "
                         f"{loops.solved_v.size} passive degrees of freedom: the actuated readings do not "
                         "determine the mechanism", source=source, field="actuated")
    return loops


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
    worst = {"cost": np.inf, "c": None}

    def tracked(q):       # the closest the Newton came: which loop would not close, for the error message
        c, jac = rows(q)
        cost = float(c @ c)
        if cost < worst["cost"]:
            worst.update(cost=cost, c=c)
        return c, jac
    label, what = (f"sample {sample}" if sample is not None else "the given input"), "closed-chain assembly"
    retract = lambda q, v: pin.integrate(model, q, v)  # noqa: E731
    try:
        q = projected_newton(tracked, q0, retract, loops.solved_v, tol, max_iter, singular_rcond, label, what)
        if q is not None:
            return q
        return damped_newton(tracked, q0, retract, free=loops.solved_v, tol=tol, max_iterations=max_iter,
                             singular_rcond=singular_rcond, sample=sample, what=what, failure=AssemblyError)
    except AssemblyError as exc:
        raise assembly_error(robot, loops, str(exc), worst["c"], sample) from None


def assembly_error(robot, loops: LoopSet, message: str, c: np.ndarray | None, sample) -> AssemblyError:
    """An AssemblyError naming the robot's file, the sample and (when a loop is left open) the loop furthest from
    closed at the best configuration reached; its attributes source, sample, constraint say the same."""
    name, error = loops.worst_closure(c[:loops.n_rows]) if c is not None and loops.n_rows else (None, 0.0)
    closed = "reached a singular configuration" in message      # the loops closed; the passive joints are free
    constraint = None if (name is None or closed) else name
    text = f"{robot.source}: {message}"
    if constraint is not None:
        kind = next(c.kind for c in loops.closures if c.name == constraint)
        text += (f"; loop '{constraint}' is the furthest from closed ({error:.3g} "
                 f"{'m' if kind in ('point', 'distance') else 'm or rad'})")
    out = AssemblyError(text)
    out.source, out.sample, out.constraint = robot.source, sample, constraint
    return out
