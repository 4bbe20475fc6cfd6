"""Results and errors of the floating-nut hexapod's kinematics (shared by the batch and single-pose solvers)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import AssemblyError

TWO_PI = 2.0 * np.pi
SINGULAR_TOL = 1e-9          # |axis x s| below this: Hooke joint in gimbal lock, roll undefined


class SingularHookeError(AssemblyError):
    """A Hooke joint's fixed axis is parallel to its strut: the nut roll is undefined there."""

    def __init__(self, message: str, sample: int | None = None, leg: int | None = None):
        self.sample, self.leg = sample, leg
        super().__init__(message)


class FKNotConverged(AssemblyError):
    """Newton forward kinematics did not reach the length tolerance (unreachable or singular)."""

    def __init__(self, message: str, sample: int | None = None):
        self.sample = sample
        super().__init__(message)


def wrap_angle(angle):
    """Wrap to (-pi, pi]."""
    return -((np.pi - angle) % TWO_PI - np.pi)


@dataclass
class IKDetails:
    """Everything the compensated IK computes, per pose and leg (N, 6), SI units."""
    lengths: np.ndarray        # effective lengths l, m
    theta: np.ndarray          # nut rotation from home, rad
    additional: np.ndarray     # l_a, m
    command: np.ndarray        # l_c = l + l_a (or l when uncompensated), m
    phi: np.ndarray            # dihedral angle, rad
    hooke: np.ndarray          # (N, 6, 4) Hooke angles q1, q2 (base), q5, q6 (platform), rad


@dataclass
class FKResult:
    """Forward-kinematics solution.

    pose        (6,) or (N, 6) platform pose [m, rad]
    iterations  int or (N,) Newton updates taken
    residual    float or (N,) final |l_c* - l_c(pose)|_inf, m
    history     max residual over the batch before each update, m
    """
    pose: np.ndarray
    iterations: np.ndarray | int
    residual: np.ndarray | float
    history: list[float]
