"""The laser/PSD fit with every DH parameter free: how many of them the data determine.

The robot is a standard-DH chain written as URDF (robocal.model.dh_urdf): joint i's placement is
[Trans_x(a_{i-1}) Rot_x(alpha_{i-1})] Rot_z(theta_i) Trans_z(d_i) and the end frame carries
Trans_x(a_n) Rot_x(alpha_n). robocal perturbs a placement by a local twist (M <- M exp6(xi)), so each
DH error is, to first order, a fixed combination of those twists:
  d_i      -> local tz of joint i's placement;          theta_i -> joint i's offset;
  a_i      -> the left translation along x of the next placement (joint i+1, or the end frame);
  alpha_i  -> the left rotation about x of that placement (the axis passes through its origin side).
A left twist xi_L of a placement M is the local twist Ad(M^-1) xi_L. The rank of the resulting
(rows x 4n + 5 + 3) Jacobian is the spec's "full-parameter mode" count (docs/laser_psd.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.systems.laser_psd.calibration import RESIDUAL, zero_offset_problem

COMPONENTS = ("tx", "ty", "tz", "rx", "ry", "rz")


@dataclass
class FullParameterRank:
    names: list[str]               # the DH parameters, then the beam's 5, then the point's 3
    singular_values: np.ndarray    # of the column-normalised Jacobian, largest first
    rank: int


def _local(M: pin.SE3, left: np.ndarray) -> np.ndarray:
    return M.inverse().act(pin.Motion(left)).vector


def dh_columns(problem, joints, end_frame: str) -> tuple[list[str], np.ndarray]:
    """(names, T): the DH parameters' Jacobian is problem.evaluate().J @ T (problem with preset "full",
    the end frame's six placement components and the beam free)."""
    robot, free = problem.robot, problem.params.free_names
    names, cols = [], []

    def column(entries):
        c = np.zeros(len(free))
        for name, v in entries:
            c[free.index(name)] += v
        return c

    def next_placement(i):
        if i + 1 < len(joints):
            jn = joints[i + 1]
            return jn, robot.model.jointPlacements[robot.joint_id(jn)]
        return end_frame, robot.model.frames[robot.frame_id(end_frame)].placement

    for i, j in enumerate(joints):
        target, M = next_placement(i)
        x_shift = _local(M, np.array([1.0, 0, 0, 0, 0, 0]))
        x_turn = _local(M, np.array([0, 0, 0, 1.0, 0, 0]))
        entries = {
            f"{j}.a": [(f"{target}.{c}", v) for c, v in zip(COMPONENTS, x_shift)],
            f"{j}.alpha": [(f"{target}.{c}", v) for c, v in zip(COMPONENTS, x_turn)],
            f"{j}.d": [(f"{j}.tz", 1.0)],
            f"{j}.theta": [(f"{j}.offset", 1.0)],
        }
        for n, e in entries.items():
            names.append(n)
            cols.append(column(e))
    for n in [f"{RESIDUAL}.origin.{c}" for c in "xyz"] + [f"{RESIDUAL}.tilt_a", f"{RESIDUAL}.tilt_b"] + \
             [f"{RESIDUAL}.target.{c}" for c in "xyz"]:
        names.append(n)
        cols.append(column([(n, 1.0)]))
    return names, np.column_stack(cols)


def full_parameter_rank(robot, joints, readings, mount, end_frame: str = "tool0", offsets=None, target=None,
                        rtol: float = 1e-8) -> FullParameterRank:
    """Rank of the DH + beam + point Jacobian at the given model (offsets, rad; PSD point, m), counting
    singular values above rtol * the largest, after scaling every non-zero column to unit norm."""
    problem = zero_offset_problem(robot, joints, readings, mount, mount_free=True, preset="full",
                                  frames={end_frame: True}, target_guess=target)
    for j, d in zip(joints, offsets if offsets is not None else np.zeros(len(joints))):
        problem.params[f"{j}.offset"].value = float(d)
    names, T = dh_columns(problem, joints, end_frame)
    J = problem.evaluate().J @ T
    norms = np.linalg.norm(J, axis=0)
    # unit columns, except those that are zero to rounding (a DH length along the beam): they stay zero
    J = J / np.where(norms > rtol * norms.max(), norms, np.inf)
    s = np.linalg.svd(J, compute_uv=False)
    return FullParameterRank(names, s, int(np.sum(s > rtol * s[0])))
