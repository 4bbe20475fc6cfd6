"""Every residual's analytic Jacobian, through the problem layer, against central finite differences."""
import numpy as np
import pinocchio as pin
import pytest

from robocal import load_example
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.testing import assert_problem_jacobian
from robocal.residuals import (BallBarResidual, CylinderResidual, LaserLineResidual, PlaneResidual,
                               PointResidual, PoseResidual, RigidPointsResidual, SphereResidual)


def _problem(residual_factory, rng):
    robot = load_example("ur5")
    robot.add_frame("tcp", "tool0", pin.SE3(pin.rpy.rpyToMatrix(0.1, -0.2, 0.3), np.array([0.01, 0.02, 0.1])))
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tcp": True}, base=True)
    for p in params:  # evaluate away from zero so exp6's Jacobian matters
        p.value = rng.normal(0, 0.01)
    n = 4
    values = rng.uniform(-2, 2, (n, len(joints)))
    res = residual_factory(np.arange(n), rng)
    problem = Problem(robot, params, joints, values, [res])
    free_auxiliaries(params, rng)
    return problem


def free_auxiliaries(params, rng):
    """Estimate every set-up quantity, starting 1 cm (or 10 mrad) off its nominal value."""
    for p in params:
        if p.kind == "auxiliary":
            p.vary = True
            p.value += rng.normal(0, 0.01)


def _q(rng, n):
    return np.array([pin.Quaternion(pin.exp3(rng.normal(size=3))).coeffs() for _ in range(n)])


FACTORIES = {
    "pose": lambda s, rng: PoseResidual("pose", "tcp", s, np.hstack([rng.normal(size=(len(s), 3)), _q(rng, len(s))])),
    "point": lambda s, rng: PointResidual("pt", "tcp", s, rng.normal(size=(len(s), 3)), point=(0.01, 0.02, 0.03)),
    "rigid_points": lambda s, rng: RigidPointsResidual("cl", "tcp", s, rng.normal(size=(len(s), 6)),
                                                       points=[[0.01, 0, 0], [0, 0.02, 0.01]]),
    "plane": lambda s, rng: PlaneResidual("pl", "tcp", s, normal=(0.1, 0.2, 1.0), offset=0.3, point=(0, 0, 0.01),
                                          tip_radius=0.003),
    "sphere": lambda s, rng: SphereResidual("sp", "tcp", s, centre=(0.3, 0.2, 0.1), radius=0.0125, point=(0, 0.01, 0.01)),
    "cylinder": lambda s, rng: CylinderResidual("cy", "tcp", s, axis_point=(0.4, 0.1, 0.0), axis_direction=(0.1, 0, 1),
                                                radius=0.02, point=(0.01, 0, 0.02), tip_radius=0.002),
    "ball_bar": lambda s, rng: BallBarResidual("bb", "tcp", s, rng.uniform(0.1, 0.2, len(s)), centre=(0.2, 0.3, 0.1),
                                               offset=0.15, point=(0, 0, 0.02)),
    "laser_line": lambda s, rng: LaserLineResidual("ls", "tcp", s, target=(0.5, 0.3, 0.2), origin=(0.01, 0.0, 0.02),
                                                   direction=(0.1, 0.1, 1.0)),
}


@pytest.mark.parametrize("kind", sorted(FACTORIES))
def test_residual_jacobian_matches_finite_differences(kind):
    rng = np.random.default_rng(7)
    problem = _problem(FACTORIES[kind], rng)
    # central differences with h=1e-6: truncation ~h^2 * third derivative, rounding ~eps/h
    assert_problem_jacobian(problem, h=1e-6, tol=1e-7)


def test_frame_parameter_moves_joints_hanging_below_it():
    """TIAGo: calibrating wrist_ft_tool_link (a fixed-joint link) moves the gripper's finger joints."""
    from pathlib import Path
    from robocal import load_urdf
    rng = np.random.default_rng(3)
    robot = load_urdf(Path(__file__).parents[1] / "examples/tiago_mocap/data/tiago_48_schunk.urdf")
    joints = robot.supporting_joints("gripper_left_fingertip_link")
    params = robot_parameters(robot, joints, "full", frames={"wrist_ft_tool_link": True})
    for p in params:
        p.value = rng.normal(0, 0.01)
    values = rng.uniform(-1, 1, (3, len(joints)))
    values[:, 0] = 0.2   # torso lift (m)
    res = PointResidual("tip", "gripper_left_fingertip_link", np.arange(3), rng.normal(size=(3, 3)))
    problem = Problem(robot, params, joints, values, [res])
    assert_problem_jacobian(problem, h=1e-6, tol=1e-7)


@pytest.mark.parametrize("order", ["parent first", "child first"])
def test_calibrated_frame_below_a_calibrated_frame_takes_both_changes_in_any_order(order):
    """tcp hangs on tool0; both calibrated: tcp = tool0 exp(d_tool0) rel exp(d_tcp), whatever the order."""
    from robocal.model.kinematics import ModelState
    from robocal.model.parameters import ParameterSet
    rng = np.random.default_rng(11)
    robot = load_example("ur5")
    rel = pin.SE3(pin.rpy.rpyToMatrix(0.1, -0.2, 0.3), np.array([0.01, 0.02, 0.1]))
    robot.add_frame("tcp", "tool0", rel)
    joints = robot.joint_names
    both = robot_parameters(robot, joints, "offsets", frames={"tool0": True, "tcp": True})
    params = ParameterSet(sorted(both, key=lambda p: (p.target != "tcp") == (order == "parent first")))
    for p in params:
        p.value = rng.normal(0, 0.05)
    ms = ModelState(robot, params, joints)
    q = rng.uniform(-2, 2, len(joints))
    s = ms.sample(q)
    nominal = robot.model.frames[robot.frame_id("tool0")].placement
    expected = nominal * pin.exp6(pin.Motion(params.placement_vector("frame_placement", "tool0"))) * rel * pin.exp6(
        pin.Motion(params.placement_vector("frame_placement", "tcp")))
    joint = s.pose("tool0") * ms.model.frames[robot.frame_id("tool0")].placement.inverse()
    np.testing.assert_allclose((joint * expected).homogeneous, s.pose("tcp").homogeneous, atol=1e-12)
    res = PointResidual("pt", "tcp", np.arange(3), rng.normal(size=(3, 3)), point=(0.01, 0.02, 0.03))
    problem = Problem(robot, params, joints, rng.uniform(-2, 2, (3, len(joints))), [res])
    assert_problem_jacobian(problem, h=1e-6, tol=1e-7)


def test_joint_compliance_parameters_match_finite_differences():
    """Compliance: q_link = q_read + offset - c * tau_g(q_read); exact derivative -tau_g per joint."""
    rng = np.random.default_rng(4)
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", base=True, compliance=True)
    for p in params:
        p.value = rng.normal(0, 1e-4 if p.kind == "joint_compliance" else 0.01)
    values = rng.uniform(-2, 2, (4, len(joints)))
    res = PoseResidual("pose", "tool0", np.arange(4), np.hstack([rng.normal(size=(4, 3)), _q(rng, 4)]))
    problem = Problem(robot, params, joints, values, [res])
    assert any(abs(problem.states()[0].tau).max() > 1.0 for _ in [0])   # UR5 carries real gravity load
    assert_problem_jacobian(problem, h=1e-6, tol=1e-7)


def test_tied_parameters_add_their_effect_to_the_leader_column():
    """Ties (a 3-3 platform's coinciding joints): the follower moves with the leader, FD-consistent."""
    rng = np.random.default_rng(5)
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True})
    params.tie("wrist_2_joint.offset", "wrist_1_joint.offset").tie("tool0.tx", "wrist_3_joint.tx")
    for p in params:
        p.value = rng.normal(0, 0.01)
    params.set_free_values(params.free_values())          # followers take their leaders' values
    assert params["wrist_2_joint.offset"].value == params["wrist_1_joint.offset"].value
    assert "wrist_2_joint.offset" not in params.free_names
    values = rng.uniform(-2, 2, (4, len(joints)))
    res = PoseResidual("pose", "tool0", np.arange(4), np.hstack([rng.normal(size=(4, 3)), _q(rng, 4)]))
    problem = Problem(robot, params, joints, values, [res])
    assert_problem_jacobian(problem, h=1e-6, tol=1e-7)
