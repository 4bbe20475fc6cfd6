"""Inverse kinematics of one frame for the motion generator: robocal.model.inverse_kinematics.frame_ik
with the generator's conventions (a 2-norm tolerance, steps capped so that a tick keeps its branch)."""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.model.inverse_kinematics import IKFailure, frame_ik

MAX_STEP = 0.5   # rad per iteration: a path tick never jumps to another branch

__all__ = ["IKFailure", "solve_ik"]


def solve_ik(model: pin.Model, data: pin.Data, frame_id: int, target: pin.SE3, q_start: np.ndarray,
             tolerance: float = 1e-10, max_iterations: int = 50, damping: float = 1e-12) -> np.ndarray:
    """q (nq,) with the frame at `target` (|log6(target^-1 M)| <= tolerance, metres / radians), warm-started
    at q_start (the previous tick's solution; docs/dynamics.md). Raises IKFailure when the target is not reached."""
    # frame_ik stops on the largest of the 6 components; below tolerance / sqrt(6) the 2-norm is within it
    return frame_ik(model, frame_id, target, q_start, data=data, tol=tolerance / np.sqrt(6.0),
                    max_iterations=max_iterations, singular_rcond=None, damping=damping, max_step=MAX_STEP)
