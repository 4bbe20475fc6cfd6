"""Inverse kinematics of one frame: damped Newton on log6, warm-started (the patent's k^-1)."""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.errors import InputError

_LOCAL = pin.ReferenceFrame.LOCAL


class IKFailure(InputError):
    """The target pose was not reached (unreachable, or too far from the warm start)."""


def solve_ik(model: pin.Model, data: pin.Data, frame_id: int, target: pin.SE3, q_start: np.ndarray,
             tolerance: float = 1e-10, max_iterations: int = 50, damping: float = 1e-12) -> np.ndarray:
    """q (nq,) with the frame at `target` (|log6| <= tolerance, metres / radians).

    Each step solves (Jl Jl^T + mu I) y = e, dq = -Jl^T y with Jl = Jlog6(err) J_local and
    mu = damping + 1e-3 |e|^2 (Levenberg-Marquardt: damped far away, exact Newton close in; minimum-
    norm steps on a redundant arm, so the warm start keeps the branch); steps are capped at 0.5 rad. Raises IKFailure if the error does not drop below `tolerance`.
    """
    q = np.array(q_start, dtype=float)
    for _ in range(max_iterations):
        pin.computeJointJacobians(model, data, q)      # fills oMi and data.J for getFrameJacobian
        pin.updateFramePlacement(model, data, frame_id)
        err_se3 = target.actInv(data.oMf[frame_id])
        err = pin.log6(err_se3).vector
        if np.linalg.norm(err) <= tolerance:
            return q
        J = pin.Jlog6(err_se3) @ pin.getFrameJacobian(model, data, frame_id, _LOCAL).reshape(6, -1)
        mu = damping + 1e-3 * float(err @ err)
        step = -J.T @ np.linalg.solve(J @ J.T + mu * np.eye(6), err)
        norm = np.linalg.norm(step)
        if norm > 0.5:
            step *= 0.5 / norm
        q = pin.integrate(model, q, step)
    pin.framesForwardKinematics(model, data, q)
    residual = np.linalg.norm(pin.log6(target.actInv(data.oMf[frame_id])).vector)
    if residual <= tolerance:
        return q
    raise IKFailure(f"inverse kinematics did not converge: pose error {residual:.3g} after "
                    f"{max_iterations} iterations (target unreachable or singular)", field="position")
