"""Loop closures: read them from URDF, evaluate their constraint rows, assemble closed chains.

A closed chain is its URDF spanning tree (loaded by Pinocchio) plus closure elements that URDF
readers ignore. Two conventions are read:

* robocal's written format, Drake's legacy ``<loop_joint>``::

    <loop_joint name="leg1_top" type="spherical|fixed|distance|revolute" [length="0.3"]>
      <link1 link="leg1_rod" xyz="0 0 0" rpy="0 0 0"/>
      <link2 link="platform" xyz="0.2 0.05 0" rpy="0 0 0"/>
      [<axis xyz="0 0 1"/>]            <!-- revolute only, in the link1 anchor frame -->
    </loop_joint>

* URDF+ (arXiv 2411.19753): ``<loop>`` (or ``<constraint>``) naming a predecessor and a successor
  link, each with an optional ``<origin>``; type fixed, revolute/continuous (``<axis>``) and, as a
  robocal extension, spherical. ``<coupling>`` (or ``<constraint type="coupling">``) with
  ``<ratio value>``: a gear or screw ties two joints.

* robocal's ``<screw_transmission>`` (a ball screw whose nut may roll; see robocal.model.joint_relations).

Couplings and screw transmissions are joint relations: one linear row each, assembled with the closures.

plus ``<actuated joints="j1 j2 ..."/>`` (or, failing that, the joints of ``<transmission>``
elements). Each closure k is anchored on two Pinocchio frames ``<name>.link1`` and ``<name>.link2``
that are added to ``robot.model``; moving a loop anchor is therefore a frame-placement edit.

Constraint kinds (rows): point 3, frame 6, distance 1, revolute 5. Derivatives are taken with
respect to a LOCAL right twist xi = [v; w] of each anchor frame (M <- M exp6(xi)).
"""
from __future__ import annotations

import copy
import logging
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.linalg.lapack import dposv

from robocal.errors import AssemblyError, InputError
from robocal.model.joint_relations import Coupling  # noqa: F401  (re-exported: loops.Coupling)

log = logging.getLogger(__name__)

ROWS = {"point": 3, "frame": 6, "distance": 1, "revolute": 5}
# closure `type` attribute -> kind, per convention
_DRAKE_KINDS = {"spherical": "point", "ball": "point", "fixed": "frame", "distance": "distance",
                "revolute": "revolute", "continuous": "revolute"}
_URDFPLUS_KINDS = {"spherical": "point", "ball": "point", "fixed": "frame",
                   "revolute": "revolute", "continuous": "revolute"}


@dataclass(frozen=True)
class Closure:
    """One loop closure between frames `frame1` and `frame2` (names of Pinocchio frames).

    kind    "point" | "frame" | "distance" | "revolute"
    rows    number of constraint rows
    length  target distance (m) for the distance kind, else 0
    axis    (3,) unit hinge axis in the frame1 anchor frame (revolute kind), else None
    """

    name: str
    kind: str
    frame1: str
    frame2: str
    rows: int
    length: float = 0.0
    axis: tuple | None = None


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _orthonormal_pair(a: np.ndarray) -> np.ndarray:
    """(2, 3): two unit vectors orthogonal to unit `a` and to each other."""
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    e1 = np.cross(a, helper)
    e1 /= np.linalg.norm(e1)
    return np.vstack([e1, np.cross(a, e1)])


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
        self._act_joints = [model.joints[model.getJointId(n)] for n in self.actuated]
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
            ck, d1, d2 = _closure_rows(closure, M1, M2)
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
            ck, d1, d2 = _closure_rows(closure, oMf[i1], oMf[i2])
            c[sl] = ck
            jac[sl] = (d1 @ pin.getFrameJacobian(model, data, i1, local).reshape(6, -1)
                       + d2 @ pin.getFrameJacobian(model, data, i2, local).reshape(6, -1))
        return c, jac

    def constraint_error(self, model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
        """c (n_rows,) at q (forward kinematics only, no Jacobians)."""
        pin.framesForwardKinematics(model, data, q)
        return self.closure_error([data.oMf[i] for i, _ in self._ids],
                                  [data.oMf[i] for _, i in self._ids])[0]


def _closure_rows(closure: Closure, M1: pin.SE3, M2: pin.SE3):
    """(c_k, D1_k, D2_k) of one closure; see LoopSet.closure_error."""
    R1, R2 = M1.rotation, M2.rotation
    kind = closure.kind
    if kind == "frame":
        M12 = M1.actInv(M2)
        jl = pin.Jlog6(M12)
        return pin.log6(M12).vector, -jl @ M12.inverse().action, jl
    d = M2.translation - M1.translation
    if kind == "distance":
        n = np.linalg.norm(d)
        u = d / n if n > 0 else np.zeros(3)  # coincident points: no direction, derivative 0
        d1, d2 = np.zeros((1, 6)), np.zeros((1, 6))
        d1[0, :3] = -(R1.T @ u)
        d2[0, :3] = R2.T @ u
        return np.array([n - closure.length]), d1, d2
    cp = R1.T @ d
    R12 = R1.T @ R2
    d1 = np.zeros((ROWS[kind], 6))
    d2 = np.zeros((ROWS[kind], 6))
    d1[:3, :3] = -np.eye(3)
    d1[:3, 3:] = _skew(cp)
    d2[:3, :3] = R12
    if kind == "point":
        return cp, d1, d2
    # revolute: point rows + the hinge axes stay aligned (two components of R12 a across a)
    a = np.asarray(closure.axis)
    E = _orthonormal_pair(a)
    b = R12 @ a
    d1[3:, 3:] = E @ _skew(b)
    d2[3:, 3:] = -E @ R12 @ _skew(a)
    return np.concatenate([cp, E @ b]), d1, d2


# ---- solving --------------------------------------------------------------------------------
def _solve(model, q, residual_jacobian, free_v, tol, max_iter, sample, what, singular_rcond):
    """Damped Gauss-Newton (Levenberg-Marquardt with mu = |c|^2) plus backtracking line search.

    residual_jacobian(q) -> (c, J) with J (m, nv); only the columns `free_v` move.
    Converges when max|c| < tol; raises AssemblyError naming `sample` otherwise, or when the
    solution is singular (smallest/largest singular value of J[:, free_v] below singular_rcond).
    """
    label = f"sample {sample}" if sample is not None else "the given readings"
    c, jac = residual_jacobian(q)
    cost = float(c @ c)
    v = np.zeros(model.nv)
    for it in range(max_iter + 1):
        a = jac[:, free_v]
        err = float(np.max(np.abs(c))) if c.size else 0.0
        if err < tol:
            s = np.linalg.svd(a, compute_uv=False)
            if s.size and s[min(a.shape) - 1] < singular_rcond * max(s[0], 1e-300):
                raise AssemblyError(
                    f"{label}: {what} reached a singular configuration (condition number "
                    f"{s[0] / max(s[min(a.shape) - 1], 1e-300):.3g}); the passive joints are not "
                    "determined by these readings")
            log.debug("%s converged in %d iterations (|c| = %.2e)", what, it, err)
            return q
        if it == max_iter:
            break
        # Levenberg-Marquardt step, damping mu = |c|^2 (vanishes at the solution: quadratic
        # convergence when regular, bounded steps near singularities); Cholesky via LAPACK
        normal = a.T @ a
        normal.flat[::normal.shape[0] + 1] += cost
        step, info = _cholesky_solve(normal, -(a.T @ c))
        if info != 0:
            step = -np.linalg.lstsq(a, c, rcond=None)[0]
        alpha, accepted = 1.0, False
        for _ in range(30):
            v[:] = 0.0
            v[free_v] = alpha * step
            q_try = pin.integrate(model, q, v)
            c_try, jac_try = residual_jacobian(q_try)
            cost_try = float(c_try @ c_try)
            if cost_try < (1.0 - 1e-4 * alpha) * cost:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            raise AssemblyError(
                f"{label}: {what} is stuck at a closure error of {err:.3g} after {it} iterations; "
                "the readings cannot be assembled (out of reach) or the configuration is singular")
        q, c, jac, cost = q_try, c_try, jac_try, cost_try
    raise AssemblyError(f"{label}: {what} did not converge in {max_iter} iterations "
                        f"(closure error {err:.3g}); the readings are out of reach or singular")


def _cholesky_solve(matrix, rhs):
    """x, info for a symmetric positive definite system (info != 0: not positive definite)."""
    _, x, info = dposv(matrix, rhs)
    return x, info


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
    return _solve(model, q0, rows, loops.solved_v, tol, max_iter, sample, "closed-chain assembly", singular_rcond)


def inverse_kinematics(robot, model: pin.Model, frame: str, target: pin.SE3, q_guess=None, sample=None,
                       tol: float = 1e-12, max_iter: int = 100, data: pin.Data | None = None,
                       singular_rcond: float = 1e-6) -> np.ndarray:
    """Generic inverse kinematics: all joints move so that `frame` reaches `target` (world SE3)
    while every closure holds. Returns q (nq,); read the actuators with
    robot.loops.actuated_values(q). Works on serial robots too (no closures)."""
    loops = robot.loops
    data = model.createData() if data is None else data
    fid = robot.frame_id(frame)
    target_inv = target.inverse()
    n_rows = loops.n_rows if loops is not None else 0

    def residual_jacobian(q):
        if loops is not None:
            c, jc = loops.constraint_jacobian(model, data, q)
            if loops.relations:   # couplings hold; a driven joint's reading is an output here
                cr, jr = loops.relation_rows(q, with_readings=False)
                c, jc = np.concatenate([c, cr]), np.vstack([jc, jr])
        else:
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacements(model, data)
            c, jc = np.zeros(0), np.zeros((0, model.nv))
        err = target_inv * data.oMf[fid]
        jf = pin.Jlog6(err) @ pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL).reshape(6, -1)
        return np.concatenate([c, pin.log6(err).vector]), np.vstack([jc, jf])

    q0 = pin.neutral(model) if q_guess is None else np.asarray(q_guess, dtype=float)
    log.debug("generic IK on %d closure rows + 6 pose rows, %d unknowns", n_rows, model.nv)
    return _solve(model, q0, residual_jacobian, np.arange(model.nv), tol, max_iter, sample,
                  "inverse kinematics", singular_rcond)
