"""The one damped-Newton IK (robocal.model.inverse_kinematics): its Jacobian, warm start, limits, failure."""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.model.inverse_kinematics import IKFailure, damped_step, pose_error, solve_ik
from robocal.model.kinematics import ModelState
from robocal.model.parameters import ParameterSet

LOCAL = pin.ReferenceFrame.LOCAL


@pytest.fixture(scope="module")
def ur5():
    return robocal.load_example("ur5")


def tool_pose(robot, q):
    data = robot.model.createData()
    pin.computeJointJacobians(robot.model, data, q)
    fid = robot.frame_id("tool0")
    pin.updateFramePlacement(robot.model, data, fid)
    return data.oMf[fid].copy(), pin.getFrameJacobian(robot.model, data, fid, LOCAL)


def test_pose_error_jacobian_matches_central_differences(ur5):
    rng = np.random.default_rng(21)
    q = rng.uniform(-2, 2, 6)
    target = tool_pose(ur5, q + rng.normal(0, 0.3, 6))[0]     # 0.3 rad away: Jlog6 far from identity
    M, J_local = tool_pose(ur5, q)
    _, J = pose_error(M, target, J_local)
    h = 1e-6
    fd = np.column_stack([(pose_error(tool_pose(ur5, pin.integrate(ur5.model, q, h * e))[0], target, J_local)[0]
                           - pose_error(tool_pose(ur5, pin.integrate(ur5.model, q, -h * e))[0], target, J_local)[0])
                          / (2 * h) for e in np.eye(6)])
    # central differences: truncation ~h^2 |e'''| ~ 1e-12, rounding ~1e-16 / h ~ 1e-10
    np.testing.assert_allclose(J, fd, rtol=0, atol=1e-8)


def test_solve_ik_keeps_the_warm_start_branch(ur5):
    q_true = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    target = tool_pose(ur5, q_true)[0]
    q = solve_ik(ur5.model, ur5.frame_id("tool0"), target, q_true + 0.2)
    np.testing.assert_allclose(q, q_true, atol=1e-9)     # the same elbow/wrist branch, not another solution


def test_unreachable_target_fails_with_a_clear_message(ur5):
    far = pin.SE3(np.eye(3), np.array([5.0, 0.0, 0.0]))   # the UR5 reaches ~0.85 m
    with pytest.raises(IKFailure, match=r"sample 7: inverse kinematics (is stuck at an error of [0-9.e+-]+ after \d+ "
                                        r"iterations|did not converge in 100 iterations \(an error of [0-9.e+-]+ "
                                        r"remains\)): out of reach"):
        solve_ik(ur5.model, "tool0", far, np.zeros(6), sample=7)
    with pytest.raises(IKFailure, match=r"^the given input: inverse kinematics did not converge in 3 iterations"):
        solve_ik(ur5.model, ur5.frame_id("tool0"), far, np.zeros(6), max_iterations=3)


def test_solve_ik_on_readings_stays_within_the_joint_limits(ur5):
    joints = ur5.joint_names
    ms = ModelState(ur5, ParameterSet(), joints)
    q_true = np.array([0.5, -1.2, 1.4, -0.5, 1.1, 0.2])
    target = tool_pose(ur5, q_true)[0]
    lower, upper = np.full(6, -np.pi), np.full(6, np.pi)
    np.testing.assert_allclose(solve_ik(ms, "tool0", target, q_true + 0.1, lower=lower, upper=upper, max_iterations=200, max_step=0.3), q_true, atol=1e-9)
    upper[0] = 0.3                                        # the base joint may not reach its 0.5 rad
    with pytest.raises(IKFailure, match="inverse kinematics"):
        solve_ik(ms, "tool0", target, q_true - 0.3, lower=lower, upper=upper, max_iterations=60, max_step=0.3)


def test_damped_step_is_the_minimum_norm_step_on_a_redundant_jacobian():
    rng = np.random.default_rng(22)
    a, r = rng.normal(size=(6, 7)), rng.normal(size=6)
    np.testing.assert_allclose(damped_step(a, r, 0.0), -np.linalg.pinv(a) @ r, atol=1e-10)
    mu = 0.5                                              # damped: the Levenberg-Marquardt step
    np.testing.assert_allclose(damped_step(a, r, mu), -np.linalg.solve(a.T @ a + mu * np.eye(7), a.T @ r), atol=1e-12)
