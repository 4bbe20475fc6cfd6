"""Inverse kinematics on log6, and the damped Newton that closed-chain assembly shares with it.

`damped_newton` drives stacked residual rows to zero: closure rows, joint-relation rows and the pose
error of a frame, e = log6(target^-1 M) with de = Jlog6(target^-1 M) J_local dq (`pose_error`). Each step
is Levenberg-Marquardt with damping mu = damping + |r|^2, which vanishes at the solution (quadratic
convergence when regular) and bounds the steps near singularities; on a redundant arm the step is the
minimum-norm one, so the warm start keeps its branch. A backtracking (Armijo) line search on |r|^2 makes
every accepted step lower the error; an optional cap limits the largest joint change per step and the
caller's `retract` may clip to joint limits. Failure is an exception that says what did not converge,
for which sample, and how far from the target it stopped.

Callers: `solve_ik`, the one IK entry point (a frame of a Pinocchio model, serial or closed chain, or the
joint readings of a calibrated robocal ModelState; the motion generator's per-tick IK and the laser/PSD plans
use it), and robocal.model.loops.assemble (closure rows only).
"""
from __future__ import annotations

import logging
from typing import Callable

import numpy as np
import pinocchio as pin
from scipy.linalg.lapack import dposv

from robocal.errors import AssemblyError

log = logging.getLogger(__name__)
LOCAL = pin.ReferenceFrame.LOCAL
ARMIJO = 1e-4            # sufficient-decrease factor of the line search
MAX_HALVINGS = 30        # line-search halvings before the solver reports it is stuck


class IKFailure(AssemblyError):
    """Inverse kinematics did not reach the target (unreachable, singular, or too far from the warm start)."""

    @property
    def reason(self) -> str:
        return str(self)


def pose_error(M: pin.SE3, target: pin.SE3, J_local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """e = log6(target^-1 M) (6,) and de/dx = Jlog6(target^-1 M) J_local, J_local (6, n) the LOCAL
    frame Jacobian of M with respect to x."""
    err = target.actInv(M)
    return pin.log6(err).vector, pin.Jlog6(err) @ np.asarray(J_local).reshape(6, -1)


def damped_newton(rows: Callable, x0: np.ndarray, retract: Callable, free=None, tol: float = 1e-12,
                  max_iterations: int = 50, damping: float = 0.0, max_step: float = np.inf,
                  singular_rcond: float | None = None, sample=None, what: str = "inverse kinematics",
                  failure: type[Exception] = AssemblyError):
    """x with max|r(x)| < tol, from the warm start x0.

    rows(x) -> (r (m,), J (m, n)): residual and its derivative for x <- retract(x, dx), dx (n,);
    free: the columns that move (default all). max_step caps max|dx| per step (rad or m).
    singular_rcond: at the solution, raise when the smallest/largest singular value of J[:, free] is
    below it (the unknowns are not determined). Raises `failure` naming `sample` when the error does not
    drop below tol in max_iterations or no step along the damped direction lowers it.
    """
    label = f"sample {sample}" if sample is not None else "the given input"
    r, jac = rows(x0)
    n = jac.shape[1]
    free = np.arange(n) if free is None else np.asarray(free, dtype=int)
    x, cost = x0, float(r @ r)
    dx = np.zeros(n)
    for it in range(max_iterations + 1):
        a = jac[:, free]
        err = float(np.max(np.abs(r))) if r.size else 0.0
        if err < tol:
            if singular_rcond is not None:
                check_regular(a, singular_rcond, label, what)
            log.debug("%s converged in %d iterations (|r| = %.2e)", what, it, err)
            return x
        if it == max_iterations:
            break
        step = damped_step(a, r, damping + cost)
        biggest = float(np.max(np.abs(step))) if step.size else 0.0
        if biggest > max_step:
            step *= max_step / biggest
        alpha = 1.0
        for _ in range(MAX_HALVINGS):
            dx[:] = 0.0
            dx[free] = alpha * step
            x_try = retract(x, dx)
            r_try, jac_try = rows(x_try)
            cost_try = float(r_try @ r_try)
            if cost_try < (1.0 - ARMIJO * alpha) * cost:
                break
            alpha *= 0.5
        else:
            raise failure(f"{label}: {what} is stuck at an error of {err:.3g} after {it} iterations: out of "
                          "reach from this start, held by a joint limit, or singular")
        x, r, jac, cost = x_try, r_try, jac_try, cost_try
    raise failure(f"{label}: {what} did not converge in {max_iterations} iterations (an error of {err:.3g} "
                  "remains): out of reach or singular")


def damped_step(a: np.ndarray, r: np.ndarray, mu: float) -> np.ndarray:
    """-(a^T a + mu I)^-1 a^T r by Cholesky (LAPACK); least squares when that is not positive definite
    (mu = 0 on a rank-deficient a: the minimum-norm step)."""
    normal = a.T @ a
    normal.flat[::normal.shape[0] + 1] += mu
    _, x, info = dposv(normal, -(a.T @ r))
    return x if info == 0 else -np.linalg.lstsq(a, r, rcond=None)[0]


def check_regular(a: np.ndarray, rcond: float, label: str, what: str) -> None:
    """Raise AssemblyError when the smallest / largest singular value of `a` is below rcond."""
    s = np.linalg.svd(a, compute_uv=False)
    if s.size and s[min(a.shape) - 1] < rcond * max(s[0], 1e-300):
        raise AssemblyError(
            f"{label}: {what} reached a singular configuration (condition number "
            f"{s[0] / max(s[min(a.shape) - 1], 1e-300):.3g}); the passive joints are not determined by these "
            "readings")


def solve_ik(robot, frame, target: pin.SE3, seed=None, *, loops=None, data: pin.Data | None = None,
             lower=None, upper=None, tol: float = 1e-12, max_iterations: int = 100, max_step: float = np.inf,
             damping: float = 0.0, singular_rcond: float | None = 1e-6, sample=None) -> np.ndarray:
    """The one inverse kinematics of robocal: the joints that put `frame` at `target` (world SE3), warm-started
    at `seed`; the error is log6(target^-1 M) and the solver stops when every component is below `tol`.

    robot: a Pinocchio model (frame: its frame id or name; returns q (nq,), seed default neutral; with `loops`,
      a robocal LoopSet, every closure and coupling holds too and all joints move - read the actuators with
      loops.actuated_values(q)), or a robocal ModelState (frame: a name; returns the joint readings of the
      calibrated model, within [lower, upper]).
    max_step caps the largest joint change per step (rad or m): it keeps the seed's branch, which keeps a sweep
    or a motion tick continuous. Raises IKFailure when the target is not reached."""
    if hasattr(robot, "sample"):
        return _reading_ik(robot, frame, target, seed, lower, upper, tol, max_iterations, max_step, damping)
    model = robot
    frame_id = model.getFrameId(frame) if isinstance(frame, str) else int(frame)
    data = model.createData() if data is None else data

    def rows(q):
        if loops is not None:
            c, jc = loops.constraint_jacobian(model, data, q)
            if loops.relations:   # couplings hold; a driven joint's reading is an output here
                cr, jr = loops.relation_rows(q, with_readings=False)
                c, jc = np.concatenate([c, cr]), np.vstack([jc, jr])
        else:
            pin.computeJointJacobians(model, data, q)     # fills oMi and data.J for getFrameJacobian
            pin.updateFramePlacement(model, data, frame_id)
            c, jc = np.zeros(0), np.zeros((0, model.nv))
        e, je = pose_error(data.oMf[frame_id], target, pin.getFrameJacobian(model, data, frame_id, LOCAL))
        return np.concatenate([c, e]), np.vstack([jc, je])

    q0 = pin.neutral(model) if seed is None else np.array(seed, dtype=float)
    return damped_newton(rows, q0, lambda q, v: pin.integrate(model, q, v), tol=tol,
                         max_iterations=max_iterations, damping=damping, max_step=max_step,
                         singular_rcond=singular_rcond, sample=sample, failure=IKFailure)


def _reading_ik(ms, frame: str, target: pin.SE3, seed, lower, upper, tol, max_iterations, max_step, damping):
    """solve_ik on a ModelState: the calibrated model's joint readings, clipped to [lower, upper]."""
    n = len(ms.joint_names)
    lower = np.full(n, -np.inf) if lower is None else np.asarray(lower, dtype=float)
    upper = np.full(n, np.inf) if upper is None else np.asarray(upper, dtype=float)
    seed = np.zeros(n) if seed is None else np.asarray(seed, dtype=float)

    def rows(v):
        s = ms.sample(v)
        return pose_error(s.pose(frame), target, s.frame_joint_jacobian(frame))

    return damped_newton(rows, np.clip(seed, lower, upper), lambda v, dv: np.clip(v + dv, lower, upper), tol=tol,
                         max_iterations=max_iterations, max_step=max_step, damping=damping, failure=IKFailure)
