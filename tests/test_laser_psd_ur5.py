"""UR5 (example-robot-data) as the second laser/PSD subject: the same code, another robot."""
import numpy as np

from robocal import load_example
from robocal.estimation.calibrate import calibrate
from robocal.model.kinematics import ModelState
from robocal.systems.laser_psd.calibration import LaserMount, laser_statements, zero_offset_problem
from robocal.systems.laser_psd.plans import multi_fan, plan_configurations
from robocal.model.parameters import robot_parameters

DELTA = np.radians([0.2, -0.3, 0.25, 0.3, -0.2, 0.25])
MOUNT = LaserMount([0.0, 0.04, 0.06], [0.0, 0.0, 1.0], frame="tool0")


def test_ur5_zero_offsets_from_three_fans_noise_free():
    robot = load_example("ur5")
    joints = robot.joint_names
    truth = robot_parameters(robot, joints, "offsets")
    for j, d in zip(joints, DELTA):
        truth[f"{j}.offset"].value = float(d)
    ms = ModelState(robot, truth, joints)
    target = np.array([0.45, 0.15, 0.05])
    direction = np.array([0.2, 0.0, -1.0]) / np.linalg.norm([0.2, 0.0, -1.0])
    q = plan_configurations(robot, ms, joints, MOUNT, multi_fan(half_angle=np.radians(30), n_per_fan=5, standoffs=0.25),
                            target, direction, roll=np.radians(-90))
    problem = zero_offset_problem(robot, joints, q, MOUNT, sigma=1e-5)
    result = calibrate(problem)
    assert result.solve.success
    # the base joint's offset is a gauge of the unknown PSD location on any arm with a vertical first axis
    assert "shoulder_pan_joint.offset" in result.unidentifiable
    est = np.array([problem.params[f"{j}.offset"].value for j in joints])
    assert np.abs(np.degrees(est - DELTA)[1:]).max() < 1e-6
    text = " ".join(laser_statements(result, problem, MOUNT))
    assert "shoulder_pan_joint" in text
