"""The Stewart URDF builder and the project's urdf/stewart_*.urdf files."""
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.model.loops import assemble
from robocal.systems.stewart import mechanism as st
from robocal.testing import assert_same_text_and_numbers

URDF = Path(__file__).resolve().parents[1] / "urdf"
GEOMETRIES = {"6_6": st.StewartGeometry.spec_6_6, "3_3": st.StewartGeometry.spec_3_3}


@pytest.mark.parametrize("name", sorted(GEOMETRIES))
def test_checked_in_urdf_is_what_the_builder_writes(name):
    text = (URDF / f"stewart_{name}.urdf").read_text()
    assert_same_text_and_numbers(text, st.build_urdf(GEOMETRIES[name](), f"stewart_{name}"), what=f"stewart_{name}.urdf")


@pytest.mark.parametrize("name", sorted(GEOMETRIES))
def test_urdf_loads_as_a_closed_chain(name):
    robot = robocal.load_urdf(URDF / f"stewart_{name}.urdf")
    model, loops = robot.model, robot.loops
    assert (model.nq, model.nv) == (25, 24)  # free-flyer platform + 6 x (U + P)
    assert loops.n_rows == 18 and loops.passive_v.size == 18
    assert loops.actuated == [f"leg{j}_slide" for j in range(1, 7)]
    assert [c.kind for c in loops.closures] == ["point"] * 6
    # the neutral configuration is the home pose, assembled at the home strut coordinates
    geometry = GEOMETRIES[name]()
    q = pin.neutral(model)
    q = loops.set_actuated(q, st.inverse_kinematics(geometry, geometry.home_pose))
    assert np.abs(loops.constraint_error(model, model.createData(), q)).max() < 1e-12


def test_3_3_joints_coincide_in_pairs():
    geometry = st.StewartGeometry.spec_3_3()
    assert len(geometry.base_joints) == len(geometry.platform_joints) == 3
    robot = robocal.load_urdf(URDF / "stewart_3_3.urdf")
    read = st.geometry_from_model(robot)
    for a, b in ((0, 1), (2, 3), (4, 5)):  # legs (B1,P1) (B1,P2) ... share base points in pairs
        np.testing.assert_array_equal(read.leg_base[a], read.leg_base[b])
    for a, b in ((1, 2), (3, 4), (5, 0)):
        np.testing.assert_array_equal(read.leg_platform[a], read.leg_platform[b])


def test_stewart_in_urdfplus_form_assembles_identically(tmp_path):
    """The same machine written with URDF+ <loop> elements (type spherical, a robocal extension)."""
    text = (URDF / "stewart_6_6.urdf").read_text()
    plus = re.sub(r'<loop_joint name="(\w+)" type="spherical">\s*<link1 link="(\w+)" xyz="([^"]*)" rpy="([^"]*)"/>'
                  r'\s*<link2 link="(\w+)" xyz="([^"]*)" rpy="([^"]*)"/>\s*</loop_joint>',
                  r'<loop name="\1" type="spherical"><predecessor link="\2"><origin xyz="\3" rpy="\4"/></predecessor>'
                  r'<successor link="\5"><origin xyz="\6" rpy="\7"/></successor></loop>', text)
    assert plus.count("<loop ") == 6 and "<loop_joint" not in plus
    path = tmp_path / "stewart_plus.urdf"
    path.write_text(plus)
    drake, urdfplus = robocal.load_urdf(URDF / "stewart_6_6.urdf"), robocal.load_urdf(path)
    geometry = st.StewartGeometry.spec_6_6()
    s = st.inverse_kinematics(geometry, pin.SE3(st.rotation_xyz([0.1, 0.2, -0.1]), geometry.home + 0.05))
    q1 = assemble(drake, drake.model, s)
    q2 = assemble(urdfplus, urdfplus.model, s)
    np.testing.assert_allclose(q1, q2, atol=1e-12)


def test_write_urdf_round_trips_a_custom_geometry(tmp_path):
    geometry = st.StewartGeometry.circular(0.5, [0, 20, 120, 140, 240, 260], 1.0, 0.2, [-30, 50, 90, 170, 210, 290],
                                           [(k, k) for k in range(6)], 0.6, (0, 0, -0.1), 0.3)
    robot = robocal.load_urdf(st.write_urdf(geometry, tmp_path / "custom.urdf", "custom"))
    read = st.geometry_from_model(robot)
    np.testing.assert_allclose(read.leg_base, geometry.leg_base, atol=1e-15)
    np.testing.assert_allclose(read.leg_platform, geometry.leg_platform, atol=1e-15)
    np.testing.assert_allclose(read.offsets, geometry.offsets, atol=1e-15)
    np.testing.assert_allclose(read.tool, geometry.tool, atol=1e-15)
    M = pin.SE3(st.rotation_xyz([0.05, -0.1, 0.1]), geometry.home + [0.02, 0.01, 0.03])
    q = assemble(robot, robot.model, st.inverse_kinematics(geometry, M))
    assert np.linalg.norm(pin.log6(M.actInv(st.platform_pose(robot, robot.model, q))).vector) < 1e-10
