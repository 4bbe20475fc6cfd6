"""The joint_backlash kind: its model equation, its Jacobian, recovery of a synthetic truth, export.

q_link = q_read + offset + b * d - c * tau_g, d the joint's approach direction at the sample.
"""
import numpy as np
import pinocchio as pin
import pytest

from robocal import load_example
from robocal.estimation.calibrate import calibrate
from robocal.model.urdf_export import calibrated_urdf
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.residuals import PoseResidual
from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from robocal.testing import assert_calibration_recovers, assert_problem_jacobian

QUAT_ID = [0, 0, 0, 0, 0, 0, 1.0]


def _pose_problem(robot, params, joints, values, directions, sigma=(5e-5, 5e-5)):
    n = len(values)
    return Problem(robot, params, joints, values,
                   [PoseResidual("poses", "tool0", np.arange(n), np.tile(QUAT_ID, (n, 1)), sigma=sigma)], directions)


def test_backlash_shifts_each_joint_by_b_towards_its_approach_direction():
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "offsets", backlash=True)
    rng = np.random.default_rng(3)
    b = rng.uniform(1e-3, 5e-3, len(joints))
    params.set_values({f"{j}.backlash": v for j, v in zip(joints, b)})
    q, d = rng.uniform(-2, 2, len(joints)), np.array([1, -1, 0, 1, -1, 1.0])
    got = ModelState(robot, params, joints).sample(q, direction=d).pose("tool0")
    want = ModelState(robot, robot_parameters(robot, joints, "none"), joints).sample(q + b * d).pose("tool0")
    assert np.abs(pin.log6(got.inverse() * want).vector).max() < 1e-12
    # without a direction (unknown) the link sits at the centre of the play: the reading itself
    centre = ModelState(robot, params, joints).sample(q).pose("tool0")
    assert np.abs(pin.log6(centre.inverse() * want).vector).max() > 1e-4


def test_problem_jacobian_with_backlash_compliance_and_placements_matches_finite_differences():
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True, compliance=True,
                              backlash=True)
    rng = np.random.default_rng(4)
    for p in params:                       # away from zero, where every term of the model is active
        p.value = rng.normal(0, 0.01)
    values = rng.uniform(-2, 2, (5, len(joints)))
    directions = rng.integers(-1, 2, values.shape).astype(float)
    problem = _pose_problem(robot, params, joints, values, directions)
    assert_problem_jacobian(problem)
    J = problem.evaluate().J
    col = params.free_names.index("elbow_joint.backlash")
    assert np.abs(J[:, col]).max() > 0.1   # the column is there, not silently zero


def test_calibration_recovers_backlash_within_the_noise_predicted_errors():
    robot = load_example("ur5")
    joints = robot.joint_names
    rng = np.random.default_rng(7)
    params = robot_parameters(robot, joints, "offsets", base=True, backlash=True)
    n = 60
    values = random_configurations(robot, joints, n, rng)
    directions = rng.choice([-1.0, 1.0], values.shape)          # known approach directions
    problem = _pose_problem(robot, params, joints, values, directions)
    # the first joint's offset is the base frame's rz again (not identifiable): leave it at zero
    truth = perturb(params, rng, 2e-3, 5e-3, patterns=[f"{j}.offset" for j in joints[1:]] + ["base.*"])
    for j in joints:                                            # half-play is positive: 1 to 5 mrad
        truth[f"{j}.backlash"].value = rng.uniform(1e-3, 5e-3)
    simulate_measurements(problem, truth, rng)
    result = assert_calibration_recovers(problem, truth)
    backlash = [f"{j}.backlash" for j in joints]
    assert set(backlash) <= set(result.estimated)     # directions of both signs: b and offset separate
    for name in backlash:   # the test can fail: each estimate is far sharper than the backlash itself
        assert result.params[name].stderr < 0.1 * truth[name].value
    written = {p["name"]: p for p in result.to_dict()["parameters"]}
    assert written["elbow_joint.backlash"]["kind"] == "joint_backlash"
    assert written["elbow_joint.backlash"]["unit"] == "rad" and written["elbow_joint.backlash"]["stderr"] > 0


def test_backlash_in_one_direction_only_is_reported_as_not_determined():
    robot = load_example("ur5")
    joints = robot.joint_names
    rng = np.random.default_rng(8)
    params = robot_parameters(robot, joints, "offsets", backlash=["elbow_joint"])
    values = random_configurations(robot, joints, 20, rng)
    directions = np.ones(values.shape)            # always approached from below: b is the offset again
    result = calibrate(_pose_problem(robot, params, joints, values, directions))
    assert result.unidentifiable == ["elbow_joint.backlash"]
    assert "elbow_joint.offset" in result.estimated


def test_problem_with_backlash_needs_directions():
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "offsets", backlash=["wrist_1_joint"])
    values = np.zeros((3, len(joints)))
    with pytest.raises(ValueError, match="wrist_1_joint.backlash.*approach direction"):
        _pose_problem(robot, params, joints, values, None)
    with pytest.raises(ValueError, match="directions have shape"):
        _pose_problem(robot, params, joints, values, np.zeros((3, 2)))


def test_export_leaves_backlash_out_of_the_urdf():
    """Backlash is not URDF geometry: it stays in result.json; the URDF carries offsets and placements."""
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", backlash=True)
    perturbed = perturb(params, np.random.default_rng(9), 2e-3, 5e-3)
    without = perturbed.copy()
    for j in joints:
        without[f"{j}.backlash"].value = 0.0
    assert any(perturbed[f"{j}.backlash"].value != 0 for j in joints)
    assert calibrated_urdf(robot, perturbed) == calibrated_urdf(robot, without)


def test_scene_draws_the_residuals_the_fit_used_with_backlash():
    """The viewer's model takes each sample's approach direction too (else it predicts at the play's centre)."""
    from robocal.viz.scene import scene_data

    robot = load_example("ur5")
    joints = robot.joint_names
    rng = np.random.default_rng(9)
    params = robot_parameters(robot, joints, "offsets", backlash=True)
    values = random_configurations(robot, joints, 12, rng)
    problem = _pose_problem(robot, params, joints, values, rng.choice([-1.0, 1.0], values.shape))
    truth = params.copy()
    for j in joints:
        truth[f"{j}.backlash"].value = 3e-3
    simulate_measurements(problem, truth, rng)
    before = params.copy()
    result = calibrate(problem)
    scene = scene_data(problem, result, before)
    (block,) = scene["blocks"]
    drawn = np.array(block["residual_after"]).reshape(-1)
    np.testing.assert_allclose(drawn, problem.evaluate().raw, atol=1e-12)
