"""Synthetic calibration problems shared by the tests."""
import numpy as np
import pinocchio as pin

from robocal import load_example
from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.residuals import PoseResidual
from robocal.design.simulate import perturb, random_configurations, simulate_measurements

IDENTITY_POSE = [0, 0, 0, 0, 0, 0, 1]


def ur5_pose_problem(rng, n_poses=60, sigma=(5e-5, 5e-5)):
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True)
    values = random_configurations(robot, joints, n_poses, rng)
    res = PoseResidual("tracker", "tool0", np.arange(n_poses), np.tile(IDENTITY_POSE, (n_poses, 1)), sigma=sigma)
    return Problem(robot, params, joints, values, [res])


def identifiable_names(problem):
    """Free parameters that survive the base-parameter selection at the nominal model."""
    from robocal.estimation.identifiability import select_base_parameters
    ev = problem.evaluate()
    sel = select_base_parameters(ev.J, problem.params.free_names)
    return [problem.params.free_names[i] for i in sel.independent]


def max_pose_error(robot, params_a, params_b, joints, frame, configs):
    """Largest |log6| difference of a frame's pose between two parameter sets over configurations."""
    a, b = ModelState(robot, params_a, joints), ModelState(robot, params_b, joints)
    return max(np.abs(pin.log6(a.sample(v).pose(frame).inverse() * b.sample(v).pose(frame)).vector).max()
               for v in configs)
