"""Closed-chain assembly (forward kinematics) and generic inverse kinematics on a planar four-bar,
checked against the circle-intersection solution, plus failure reporting."""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.errors import AssemblyError
from robocal.model.inverse_kinematics import solve_ik
from robocal.model.loops import assemble

A, B, C, D = 0.1, 0.3, 0.25, 0.3  # crank, coupler, rocker, ground (m)
FOURBAR = f"""<robot name="fourbar">
  <link name="ground"/><link name="crank_link"/><link name="coupler_link"/><link name="rocker_link"/>
  <joint name="crank" type="revolute"><parent link="ground"/><child link="crank_link"/>
    <axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
  <joint name="coupler_joint" type="continuous"><parent link="crank_link"/><child link="coupler_link"/>
    <origin xyz="{A} 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="rocker" type="revolute"><parent link="ground"/><child link="rocker_link"/>
    <origin xyz="{D} 0 0"/><axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
  <loop_joint name="pin" type="revolute"><axis xyz="0 0 1"/>
    <link1 link="coupler_link" xyz="{B} 0 0"/><link2 link="rocker_link" xyz="{C} 0 0"/></loop_joint>
  <actuated joints="crank"/>
</robot>"""


@pytest.fixture(scope="module")
def fourbar(tmp_path_factory):
    path = tmp_path_factory.mktemp("fourbar") / "fourbar.urdf"
    path.write_text(FOURBAR)
    return robocal.load_urdf(path)


def rocker_angles(theta):
    """Both assembly branches of the rocker angle for crank angle theta (circle intersection)."""
    a = np.array([A * np.cos(theta), A * np.sin(theta)])
    dvec = np.array([D, 0.0]) - a
    dist = np.linalg.norm(dvec)
    # B lies on circle(a, B) and circle(D, C): foot of the chord along dvec, then +- perpendicular
    x = (B**2 - C**2 + dist**2) / (2 * dist)
    h = np.sqrt(B**2 - x**2)
    e, n = dvec / dist, np.array([-dvec[1], dvec[0]]) / dist
    tips = [a + x * e + h * n, a + x * e - h * n]
    return [np.arctan2(t[1], t[0] - D) for t in tips]


def angles(robot, q):
    j = robot.model.joints[robot.joint_id("coupler_joint")]
    return q[robot.model.joints[robot.joint_id("rocker")].idx_q], np.arctan2(q[j.idx_q + 1], q[j.idx_q])


def test_assembly_matches_the_circle_intersection_on_both_branches(fourbar):
    data = fourbar.model.createData()
    for theta in np.linspace(-np.pi, np.pi, 13):
        for expected in rocker_angles(theta):
            # start 0.2 rad away from the branch on both passive joints: Newton must land on it
            tip = np.array([D + C * np.cos(expected), C * np.sin(expected)])
            coupler = np.arctan2(tip[1] - A * np.sin(theta), tip[0] - A * np.cos(theta)) - theta
            guess = fourbar.configuration(["rocker", "coupler_joint"], [expected + 0.2, coupler - 0.2])
            q = assemble(fourbar, fourbar.model, [theta], q_guess=guess, data=data)
            assert abs(np.angle(np.exp(1j * (angles(fourbar, q)[0] - expected)))) < 1e-10
            assert np.abs(fourbar.loops.constraint_error(fourbar.model, data, q)).max() < 1e-12
            assert fourbar.loops.actuated_values(q)[0] == pytest.approx(theta, abs=1e-15)


def test_warm_start_stays_on_the_branch_of_the_previous_solution(fourbar):
    q = assemble(fourbar, fourbar.model, [0.0], q_guess=fourbar.configuration(["rocker"], [-2.0]))
    for theta in np.linspace(0.0, 2 * np.pi, 25)[1:]:  # one full crank turn, small steps
        q = assemble(fourbar, fourbar.model, [theta], q_guess=q)
        low_branch = min(rocker_angles(theta), key=lambda r: np.sin(r))
        assert abs(np.angle(np.exp(1j * (angles(fourbar, q)[0] - low_branch)))) < 1e-10


def test_calibrated_copy_with_edited_placements_is_assembled(fourbar):
    model = fourbar.model.copy()
    rocker = fourbar.joint_id("rocker")
    model.jointPlacements[rocker] = pin.SE3(np.eye(3), np.array([D + 0.02, 0.0, 0.0]))  # longer ground
    q = assemble(fourbar, model, [0.4], q_guess=fourbar.configuration(["rocker"], [2.0]))
    assert np.abs(fourbar.loops.constraint_error(model, model.createData(), q)).max() < 1e-12
    # the nominal model at the same q no longer closes: the edit was used
    assert np.abs(fourbar.loops.constraint_error(fourbar.model, fourbar.model.createData(), q)).max() > 1e-3


def test_unreachable_readings_name_the_sample(tmp_path):
    # a 0.26 m crank cannot turn fully: at theta = pi its tip is 0.56 m from the rocker pivot,
    # beyond coupler + rocker = 0.55 m, so there is no assembly
    path = tmp_path / "short.urdf"
    path.write_text(FOURBAR.replace(f'<origin xyz="{A} 0 0"/>', '<origin xyz="0.26 0 0"/>'))
    robot = robocal.load_urdf(path)
    with pytest.raises(AssemblyError, match="sample 12"):
        assemble(robot, robot.model, [np.pi], q_guess=robot.configuration(["rocker"], [2.0]), sample=12)


def test_singular_assembly_is_reported(tmp_path):
    # rocker shortened to 0.1 m: at theta = 0 the crank tip (0.1, 0) is |AD| = 0.2 m = coupler - rocker
    # from the rocker pivot, so coupler and rocker fold onto one line (a tangent, singular assembly)
    path = tmp_path / "dead.urdf"
    path.write_text(FOURBAR.replace(f'xyz="{C} 0 0"/></loop_joint>', 'xyz="0.1 0 0"/></loop_joint>'))
    robot = robocal.load_urdf(path)
    guess = robot.configuration(["rocker", "coupler_joint"], [0.3, 0.2])
    with pytest.raises(AssemblyError, match="sample 5: .*singular"):
        assemble(robot, robot.model, [0.0], q_guess=guess, sample=5)


def test_generic_inverse_kinematics_reaches_a_target_on_the_closed_chain(fourbar):
    data = fourbar.model.createData()
    q_true = assemble(fourbar, fourbar.model, [1.1], q_guess=fourbar.configuration(["rocker"], [2.0]))
    pin.framesForwardKinematics(fourbar.model, data, q_true)
    fid = fourbar.frame_id("coupler_link")
    target = data.oMf[fid].copy()
    guess = fourbar.configuration(["crank", "rocker"], [0.9, 1.9])
    # the coupler pose (planar: x, y, angle) fixes the mechanism; out-of-plane rows are redundant
    q = solve_ik(fourbar.model, fid, target, guess, loops=fourbar.loops)
    assert fourbar.loops.actuated_values(q)[0] == pytest.approx(1.1, abs=1e-10)
    pin.framesForwardKinematics(fourbar.model, data, q)
    assert np.linalg.norm(pin.log6(target.actInv(data.oMf[fid])).vector) < 1e-12


def test_generic_inverse_kinematics_on_a_serial_arm():
    robot = robocal.load_example("ur5")
    data = robot.model.createData()
    q_true = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    pin.framesForwardKinematics(robot.model, data, q_true)
    target = data.oMf[robot.frame_id("tool0")].copy()
    q = solve_ik(robot.model, robot.frame_id("tool0"), target, q_true + 0.05)
    np.testing.assert_allclose(q, q_true, atol=1e-9)


def test_distance_closure_assembles_like_a_coupler_link(tmp_path):
    """The coupler replaced by a fixed-distance closure (a ball bar of length B) between the crank
    tip and the rocker tip: the rocker angle must be the same circle intersection."""
    text = f"""<robot name="bar">
  <link name="ground"/><link name="crank_link"/><link name="rocker_link"/>
  <joint name="crank" type="revolute"><parent link="ground"/><child link="crank_link"/>
    <axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
  <joint name="rocker" type="revolute"><parent link="ground"/><child link="rocker_link"/>
    <origin xyz="{D} 0 0"/><axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
  <loop_joint name="bar" type="distance" length="{B}">
    <link1 link="crank_link" xyz="{A} 0 0"/><link2 link="rocker_link" xyz="{C} 0 0"/></loop_joint>
  <actuated joints="crank"/>
</robot>"""
    path = tmp_path / "bar.urdf"
    path.write_text(text)
    robot = robocal.load_urdf(path)
    rocker = robot.model.joints[robot.joint_id("rocker")].idx_q
    for theta in np.linspace(-3.0, 3.0, 7):
        for expected in rocker_angles(theta):
            q = assemble(robot, robot.model, [theta], q_guess=robot.configuration(["rocker"], [expected + 0.2]))
            assert abs(np.angle(np.exp(1j * (q[rocker] - expected)))) < 1e-10


def test_a_closed_chain_robot_pickles_and_assembles_alike(fourbar):
    """Robots travel to Dask workers by pickle: the loop set keeps index slots, not Pinocchio joint models."""
    import pickle
    copy = pickle.loads(pickle.dumps(fourbar))
    for theta in (-1.0, 0.3, 2.0):
        q = assemble(fourbar, fourbar.model, [theta])
        q_copy = assemble(copy, copy.model, [theta])
        np.testing.assert_array_equal(q, q_copy)
        assert copy.loops.actuated_values(q_copy)[0] == pytest.approx(theta, abs=1e-15)
