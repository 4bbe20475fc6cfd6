"""The posture the force-regulation tests share: a UR5 at Q0, and a frame's pose there."""
import numpy as np
import pinocchio as pin

Q0 = np.array([0.3, -1.2, 1.5, -1.9, -1.5, 0.2])


def frame_pose(model: pin.Model, fid: int, q: np.ndarray = Q0) -> pin.SE3:
    """World pose of frame `fid` at configuration q."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[fid].copy()
