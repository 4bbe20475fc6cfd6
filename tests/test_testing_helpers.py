"""robocal.testing: each assertion passes on a good input and fails, naming what broke, on a broken one."""
import numpy as np
import pytest

from robocal import load_example
from robocal.model.kinematics import ModelState, SampleState
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.residuals import PointResidual
from robocal.testing import (assert_calibration_recovers, assert_frame_jacobians, assert_jacobian_matches_fd,
                             assert_problem_jacobian, assert_urdf_loads, synthetic_pose_case)


def _f(x):
    return np.array([np.sin(x[0]) * x[1], x[1] ** 2, np.exp(x[2]) + x[0]])


def _J(x):
    return np.array([[np.cos(x[0]) * x[1], np.sin(x[0]), 0.0], [0.0, 2 * x[1], 0.0], [1.0, 0.0, np.exp(x[2])]])


def test_generic_jacobian_passes_when_right_and_names_the_one_wrong_column():
    x0 = np.array([0.3, -0.7, 0.2])
    assert assert_jacobian_matches_fd(_f, x0, _J(x0), names=["a", "b", "c"]) < 1e-8
    J = _J(x0)
    J[1, 1] *= -1.0
    with pytest.raises(AssertionError) as info:
        assert_jacobian_matches_fd(_f, x0, J, names=["a", "b", "c"], rows=["r0", "r1", "r2"])
    msg = str(info.value)
    assert "in 1 of 3 columns" in msg and "  b: worst at r1" in msg
    assert "  a:" not in msg and "  c:" not in msg


def test_generic_jacobian_reports_shape_and_nan():
    x0 = np.zeros(3)
    with pytest.raises(AssertionError, match="shape"):
        assert_jacobian_matches_fd(_f, x0, np.zeros((3, 2)))
    J = _J(x0)
    J[2, 2] = np.nan
    with pytest.raises(AssertionError, match="column 2: worst at row 2"):
        assert_jacobian_matches_fd(_f, x0, J)


class BrokenPoint(PointResidual):
    """A marker residual whose derivative w.r.t. the marker's y coordinate is twice too large."""

    def evaluate(self, k, states, aux):
        t = super().evaluate(k, states, aux)
        t.aux = t.aux.copy()
        t.aux[:, 1] *= 2.0
        return t


def _marker_problem(cls, seed=5):
    rng = np.random.default_rng(seed)
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True)
    for p in params:
        p.value = rng.normal(0, 0.01)   # away from zero, so exp6's Jacobian matters
    values = rng.uniform(-2, 2, (3, len(joints)))
    res = cls("marker", "tool0", np.arange(3), rng.normal(size=(3, 3)), point=(0.01, 0.02, 0.03),
              point_unknown=True)
    return Problem(robot, params, joints, values, [res])


def test_problem_jacobian_passes_and_names_the_broken_auxiliary_column():
    assert assert_problem_jacobian(_marker_problem(PointResidual)) < 1e-7
    problem = _marker_problem(BrokenPoint)
    x_before = problem.params.free_values()
    with pytest.raises(AssertionError) as info:
        assert_problem_jacobian(problem)
    msg = str(info.value)
    assert "residual Jacobian" in msg and "in 1 of" in msg and "  marker.point.y: worst at block 'marker'" in msg
    np.testing.assert_array_equal(problem.params.free_values(), x_before)   # parameters restored


class _FlippedSample(SampleState):
    def frame_parameter_jacobian(self, frame):
        J = super().frame_parameter_jacobian(frame).copy()
        J[:, self.ms.params.free_names.index("elbow_joint.offset")] *= -1.0
        return J


class _FlippedState(ModelState):
    def sample(self, values, q_guess=None, label=None):
        return _FlippedSample(self, np.asarray(values, dtype=float), label)


def test_frame_jacobians_pass_and_a_flipped_parameter_column_is_named():
    rng = np.random.default_rng(2)
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True)
    for p in params:
        p.value = rng.normal(0, 0.01)
    values = rng.uniform(-2, 2, len(joints))
    assert_frame_jacobians(robot, params, joints, values, "tool0")
    with pytest.raises(AssertionError) as info:
        assert_frame_jacobians(robot, params, joints, values, "tool0", model_state=_FlippedState)
    msg = str(info.value)
    assert "frame 'tool0' parameter Jacobian" in msg and "in 1 of 54 columns" in msg
    assert "  elbow_joint.offset: worst at tool0.w" in msg


def test_calibration_recovers_a_synthetic_truth():
    case = synthetic_pose_case("ur5", 40, seed=3)
    result = assert_calibration_recovers(case.problem, case.truth)
    assert result.estimated == case.identifiable


def test_a_wrong_truth_names_the_parameter():
    case = synthetic_pose_case("ur5", 40, seed=3)
    wrong = case.truth.copy()
    assert "elbow_joint.tz" in case.identifiable
    # Its standard error here is ~8 um (50 um noise, 240 rows): 1 mm is over 100 of them.
    wrong["elbow_joint.tz"].value += 1e-3
    with pytest.raises(AssertionError) as info:
        assert_calibration_recovers(case.problem, wrong)
    msg = str(info.value)
    lines = msg.splitlines()
    assert "does not recover the truth" in lines[0]
    assert lines[1].startswith("  elbow_joint.tz: estimate")   # the worst parameter comes first
    assert "standard errors" in lines[1]


def test_misstated_noise_is_reported():
    case = synthetic_pose_case("ur5", 40, seed=4)
    case.problem.residuals[0].sigma = case.problem.residuals[0].sigma / 2   # data have twice the stated noise
    with pytest.raises(AssertionError, match="the stated sigmas do not describe the residuals"):
        assert_calibration_recovers(case.problem, case.truth)


def test_synthetic_case_is_deterministic_in_its_seed():
    a, b = synthetic_pose_case("ur5", 10, seed=8), synthetic_pose_case("ur5", 10, seed=8)
    np.testing.assert_array_equal(a.problem.values, b.problem.values)
    np.testing.assert_array_equal(a.problem.residuals[0].measurements, b.problem.residuals[0].measurements)
    c = synthetic_pose_case("ur5", 10, seed=9)
    assert not np.array_equal(a.problem.values, c.problem.values)


def test_urdf_loads_with_frames_and_names_a_missing_one(tmp_path):
    robot = assert_urdf_loads("ur5", ["tool0", "wrist_3_link"])
    assert robot.name == "ur5"
    with pytest.raises(AssertionError, match=r"1 of 2 frames missing:\n  robot 'ur5' has no frame 'tool1'\. "
                                             r"Close matches: tool0"):
        assert_urdf_loads("ur5", ["tool0", "tool1"])
    bad = tmp_path / "broken.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot>")
    with pytest.raises(AssertionError, match=r"broken.urdf does not load: .*not valid XML"):
        assert_urdf_loads(bad)


FOURBAR = """<robot name="fourbar">
  <link name="ground"/><link name="crank_link"/><link name="coupler_link"/><link name="rocker_link"/>
  <joint name="crank" type="revolute"><parent link="ground"/><child link="crank_link"/>
    <axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
  <joint name="coupler_joint" type="continuous"><parent link="crank_link"/><child link="coupler_link"/>
    <origin xyz="0.1 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="rocker" type="revolute"><parent link="ground"/><child link="rocker_link"/>
    <origin xyz="0.3 0 0" rpy="0 0 1.5707963"/><axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
  <loop_joint name="pin" type="spherical">
    <link1 link="coupler_link" xyz="COUPLER 0 0"/><link2 link="rocker_link" xyz="0.25 0 0"/></loop_joint>
  <actuated joints="crank"/>
</robot>"""


def test_closed_chain_assembles_at_home_and_an_impossible_one_is_reported(tmp_path):
    """Applies to robots with loop closures (robocal.model.loops); planar four-bar, crank at 0 = home."""
    good = tmp_path / "fourbar.urdf"
    good.write_text(FOURBAR.replace("COUPLER", "0.3"))
    robot = assert_urdf_loads(good, ["pin.link1"])
    assert robot.loops is not None
    short = tmp_path / "short.urdf"
    # At crank 0 the crank tip is 0.2 m from the rocker pivot; a 0.02 m coupler and a 0.25 m rocker
    # span only |0.25 - 0.02| = 0.23 m or more, so the loop cannot close.
    short.write_text(FOURBAR.replace("COUPLER", "0.02"))
    with pytest.raises(AssertionError, match="closures do not assemble at the home pose"):
        assert_urdf_loads(short, home=[0.0])


def test_same_text_and_numbers_tolerates_last_bits_only():
    from robocal.testing import assert_same_text_and_numbers
    a = '<origin xyz="0.1 0.55 -0.2" rpy="0 0 1.5707963267948966"/>'
    assert_same_text_and_numbers(a, a.replace("0.55", "0.55000000000000004"))   # one ulp: same
    with pytest.raises(AssertionError, match="numbers differ"):
        assert_same_text_and_numbers(a, a.replace("0.55", "0.550000001"))       # 1 nm: not the same
    with pytest.raises(AssertionError, match="outside its numbers"):
        assert_same_text_and_numbers(a, a.replace("rpy", "xyz"))
