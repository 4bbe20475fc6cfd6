"""Joint-space image of a Cartesian path, h(s) = k^-1(f(s)) (spec §4-C "joint limits").

Along a Cartesian path the joints follow h(s), the inverse kinematics of the pose at s. Its
derivatives come from the frame Jacobian J (6 x n, LOCAL_WORLD_ALIGNED) and the pose derivatives
xi' = [f'; w'], xi'' = [f''; w''] (classical linear acceleration, angular acceleration):
    J h' = xi',    J h'' + c(h, h') = xi''
where c is the frame's classical acceleration for joint velocity h' and zero joint acceleration
(Pinocchio's getFrameClassicalAcceleration). With h', h'' the per-axis velocity and acceleration
limits project onto s exactly as for a joint path (limits.project_limits). Position limits cannot
be projected onto a fixed path: a path that leaves them is refused (`check_position_limits`).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.errors import InputError

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def joint_derivatives(model: pin.Model, data: pin.Data, frame_id: int, q: np.ndarray, df: np.ndarray,
                      ddf: np.ndarray, dw: np.ndarray, ddw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(h', h'') (nv,) at the configuration q = h(s) for pose derivatives f', f'' (m) and w', w''
    (rad) in s. Least squares (minimum norm) when J is not square."""
    J = pin.computeFrameJacobian(model, data, q, frame_id, _LWA)
    dh = np.linalg.lstsq(J, np.r_[df, dw], rcond=None)[0]
    pin.forwardKinematics(model, data, q, dh, np.zeros(model.nv))
    drift = pin.getFrameClassicalAcceleration(model, data, frame_id, _LWA).vector
    ddh = np.linalg.lstsq(J, np.r_[ddf, ddw] - drift, rcond=None)[0]
    return dh, ddh


def check_position_limits(model: pin.Model, q: np.ndarray, s: float, margin: float = 1e-12) -> None:
    """Raise InputError naming the joint, its value and the limit when q lies outside the model's
    position limits (the path would drive that joint past its stop at parameter s)."""
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    for i in range(model.nq):
        if q[i] < lo[i] - margin or q[i] > hi[i] + margin:
            joint = next(j for j in range(1, model.njoints)
                         if model.joints[j].idx_q <= i < model.joints[j].idx_q + model.joints[j].nq)
            side, limit = ("lower", lo[i]) if q[i] < lo[i] else ("upper", hi[i])
            raise InputError(f"the path drives joint '{model.names[joint]}' past its {side} limit at s = {s:.3f}: "
                             f"{q[i]:.4f} vs {limit:.4f} rad", field="position")
