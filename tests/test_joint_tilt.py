"""The joint_tilt kind: its model equation (checked against subtree centres of mass), its Jacobian,
recovery of a synthetic truth, and where it is refused.

The child side of a joint rotates by -t * M_perp about the joint origin, M_perp the gravity moment across
the joint axis.
"""
import numpy as np
import pinocchio as pin
import pytest

from robocal import load_example
from robocal.model.urdf_export import calibrated_urdf
from robocal.model.batch_kinematics import supports_batch
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.residuals import PoseResidual
from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from robocal.testing import assert_calibration_recovers, assert_problem_jacobian

QUAT_ID = [0, 0, 0, 0, 0, 0, 1.0]


def _pose_problem(robot, params, joints, values, sigma=(5e-5, 5e-5)):
    n = len(values)
    return Problem(robot, params, joints, values,
                   [PoseResidual("poses", "tool0", np.arange(n), np.tile(QUAT_ID, (n, 1)), sigma=sigma)])


def _tilted_by_hand(robot, joint, t, q):
    """Pose of tool0 with `joint`'s placement rotated by -t M_perp, M summed over the subtree's bodies."""
    model = robot.model.copy()
    data = model.createData()
    jid = model.getJointId(joint)
    pin.forwardKinematics(model, data, q)
    origin = data.oMi[model.parents[jid]] * model.jointPlacements[jid]
    support = np.zeros(3)                                  # what the parent must hold against gravity
    for i in model.subtrees[jid]:
        body = model.inertias[i]
        support -= np.cross(data.oMi[i].act(body.lever) - origin.translation, body.mass * model.gravity.linear)
    m_local = origin.rotation.T @ support
    axis = model.joints[jid].shortname()[-1]                             # UR5: RX / RY / RZ joints
    a = np.eye(3)["XYZ".index(axis)]
    m_perp = m_local - m_local.dot(a) * a
    model.jointPlacements[jid] = model.jointPlacements[jid] * pin.SE3(pin.exp3(-t * m_perp), np.zeros(3))
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId("tool0")], np.linalg.norm(m_perp)


@pytest.mark.parametrize("joint", ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint"])
def test_tilt_rotates_the_child_side_by_the_gravity_moment_across_the_axis(joint):
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "none", tilt=[joint])
    t = 2e-3
    params[f"{joint}.tilt"].value = t
    rng = np.random.default_rng(1)
    for values in random_configurations(robot, joints, 4, rng):
        got = ModelState(robot, params, joints).sample(values).pose("tool0")
        want, moment = _tilted_by_hand(robot, joint, t, robot.configuration(joints, values))
        assert moment > 1.0                                  # a real load: the tilt is t * moment > 2 mrad
        assert np.abs(pin.log6(got.inverse() * robot.base_placement * want).vector).max() < 1e-12


def test_problem_jacobian_with_tilt_and_placements_matches_finite_differences():
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True, compliance=True,
                              tilt=True)
    rng = np.random.default_rng(4)
    for p in params:                       # away from zero, where every term of the model is active
        p.value = rng.normal(0, 0.01)
    problem = _pose_problem(robot, params, joints, rng.uniform(-2, 2, (5, len(joints))))
    assert supports_batch(problem.model_state())       # the batched pass (joint_tilt_arrays) is what is checked
    assert_problem_jacobian(problem)
    J = problem.evaluate().J
    assert np.abs(J[:, params.free_names.index("shoulder_lift_joint.tilt")]).max() > 1.0   # not silently zero


def test_calibration_recovers_tilts_within_the_noise_predicted_errors():
    robot = load_example("ur5")
    joints = robot.joint_names
    rng = np.random.default_rng(7)
    # the two joints that carry a large moment across their axis (the rest bend under a few N m only)
    tilted = ["shoulder_pan_joint.tilt", "shoulder_lift_joint.tilt"]
    params = robot_parameters(robot, joints, "offsets", base=True, tilt=[n.split(".")[0] for n in tilted])
    values = random_configurations(robot, joints, 40, rng)
    problem = _pose_problem(robot, params, joints, values)
    truth = perturb(params, rng, 2e-3, 5e-3, patterns=[f"{j}.offset" for j in joints[1:]] + ["base.*"])
    for name in tilted:
        truth[name].value = rng.uniform(2e-5, 1e-4)             # 0.2-1 mrad at 10 N m
    simulate_measurements(problem, truth, rng)
    result = assert_calibration_recovers(problem, truth)
    for name in tilted:
        assert name in result.estimated
        assert result.params[name].stderr < 0.2 * truth[name].value    # sharply determined, so can fail
    written = {p["name"]: p for p in result.to_dict()["parameters"]}
    assert written["shoulder_pan_joint.tilt"]["kind"] == "joint_tilt"
    assert written["shoulder_pan_joint.tilt"]["unit"] == "rad/(N m)"


def test_export_leaves_tilt_out_of_the_urdf():
    """A load-dependent bend is not URDF geometry: it stays in result.json."""
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", tilt=True)
    perturbed = perturb(params, np.random.default_rng(9), 2e-3, 5e-3)
    without = perturbed.copy()
    for j in joints:
        perturbed[f"{j}.tilt"].value = 1e-4
        without[f"{j}.tilt"].value = 0.0
    assert calibrated_urdf(robot, perturbed) == calibrated_urdf(robot, without)


def test_tilt_on_a_closed_chain_is_refused():
    from pathlib import Path

    from robocal import load_urdf
    robot = load_urdf(Path(__file__).parents[1] / "urdf" / "stewart_6_6.urdf")
    params = robot_parameters(robot, [], "none", tilt=[robot.loops.actuated[0]])
    with pytest.raises(ValueError, match="joint_tilt parameters are supported on serial"):
        ModelState(robot, params, robot.loops.actuated)


def test_joint_axis_of_revolute_prismatic_and_other_joints():
    from pathlib import Path

    from robocal import load_urdf
    ur5 = load_example("ur5")
    axis, revolute = ur5.joint_axis(ur5.joint_id("shoulder_lift_joint"))
    assert revolute and np.allclose(axis, [0, 1, 0])                   # UR5's shoulder turns about its y
    tiago = load_urdf(Path(__file__).parents[1] / "examples" / "tiago_mocap" / "data" / "tiago_48_schunk.urdf")
    axis, revolute = tiago.joint_axis(tiago.joint_id("torso_lift_joint"))
    assert not revolute and np.allclose(axis, [0, 0, 1])               # the torso lifts along z
    stewart = load_urdf(Path(__file__).parents[1] / "urdf" / "stewart_6_6.urdf")
    several = next(j for j in range(1, stewart.model.njoints) if stewart.model.joints[j].nv > 1)
    assert stewart.joint_axis(several) is None
