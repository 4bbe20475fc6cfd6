"""Reading loop closures from URDF: Drake's <loop_joint> and URDF+ <loop>/<constraint>/<coupling>."""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.errors import InputError
from robocal.model.kinematics import ModelState
from robocal.model.loops import assemble
from robocal.model.parameters import Parameter, ParameterSet
from robocal.testing import assert_frame_jacobians

# A planar four-bar (crank 0.1, coupler 0.3, rocker 0.25, ground 0.3 m) closed at the coupler/rocker pin.
TREE = """
  <link name="ground"/><link name="crank_link"/><link name="coupler_link"/><link name="rocker_link"/>
  <joint name="crank" type="revolute"><parent link="ground"/><child link="crank_link"/>
    <origin xyz="0 0 0"/><axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
  <joint name="coupler_joint" type="continuous"><parent link="crank_link"/><child link="coupler_link"/>
    <origin xyz="0.1 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="rocker" type="revolute"><parent link="ground"/><child link="rocker_link"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
"""
DRAKE = f"""<robot name="fourbar">{TREE}
  <loop_joint name="pin" type="revolute"><axis xyz="0 0 1"/>
    <link1 link="coupler_link" xyz="0.3 0 0" rpy="0 0 0.2"/><link2 link="rocker_link" xyz="0.25 0 0"/>
  </loop_joint>
  <actuated joints="crank"/>
</robot>"""
URDFPLUS = f"""<robot name="fourbar">{TREE}
  <loop name="pin" type="revolute">
    <predecessor link="coupler_link"><origin xyz="0.3 0 0" rpy="0 0 0.2"/></predecessor>
    <successor link="rocker_link"><origin xyz="0.25 0 0"/></successor>
    <axis xyz="0 0 1"/>
  </loop>
  <actuated joints="crank"/>
</robot>"""


def load(tmp_path, text, name="robot.urdf"):
    path = tmp_path / name
    path.write_text(text)
    return robocal.load_urdf(path)


def test_tree_robot_has_no_loops():
    assert robocal.load_example("ur5").loops is None


CONSTRAINT = URDFPLUS.replace("<loop ", "<constraint ").replace("</loop>", "</constraint>")


@pytest.mark.parametrize("text", [DRAKE, URDFPLUS, CONSTRAINT],
                         ids=["drake_loop_joint", "urdfplus_loop", "urdfplus_constraint"])
def test_both_conventions_read_the_same_closure(tmp_path, text):
    robot = load(tmp_path, text)
    loops = robot.loops
    assert [c.name for c in loops.closures] == ["pin"]
    closure = loops.closures[0]
    assert (closure.kind, closure.rows, closure.frame1, closure.frame2) == ("revolute", 5, "pin.link1", "pin.link2")
    np.testing.assert_allclose(closure.axis, [0, 0, 1])
    assert loops.actuated == ["crank"] and loops.passive == ["coupler_joint", "rocker"]
    # anchors: frames on the named links at the given xyz/rpy
    f1 = robot.model.frames[robot.frame_id("pin.link1")]
    f2 = robot.model.frames[robot.frame_id("pin.link2")]
    assert robot.model.names[f1.parentJoint] == "coupler_joint"
    assert robot.model.names[f2.parentJoint] == "rocker"
    expected1 = pin.SE3(pin.rpy.rpyToMatrix(0, 0, 0.2), np.array([0.3, 0, 0]))
    assert np.allclose(f1.placement.homogeneous, expected1.homogeneous, atol=1e-15)
    assert np.allclose(f2.placement.translation, [0.25, 0, 0], atol=1e-15)
    # the same mechanism: both conventions assemble to the same configuration
    q = assemble(robot, robot.model, [0.7], q_guess=robot.configuration(["coupler_joint", "rocker"], [0.5, 1.5]))
    c = loops.constraint_error(robot.model, robot.model.createData(), q)
    assert np.abs(c).max() < 1e-12


def test_point_frame_distance_kinds_and_transmission_fallback(tmp_path):
    text = f"""<robot name="kinds">{TREE}
  <loop_joint name="ball" type="spherical">
    <link1 link="coupler_link" xyz="0.3 0 0"/><link2 link="rocker_link" xyz="0.25 0 0"/></loop_joint>
  <loop_joint name="weld" type="fixed">
    <link1 link="coupler_link" xyz="0.3 0 0"/><link2 link="rocker_link" xyz="0.25 0 0" rpy="0 0 1"/></loop_joint>
  <loop_joint name="bar" type="distance" length="0.3">
    <link1 link="crank_link" xyz="0.1 0 0"/><link2 link="rocker_link" xyz="0.25 0 0"/></loop_joint>
  <transmission name="t1"><type>transmission_interface/SimpleTransmission</type>
    <joint name="crank"/></transmission>
</robot>"""
    loops = load(tmp_path, text).loops
    assert [(c.kind, c.rows) for c in loops.closures] == [("point", 3), ("frame", 6), ("distance", 1)]
    assert loops.closures[2].length == pytest.approx(0.3)
    assert loops.n_rows == 10 and loops.actuated == ["crank"]


def test_urdfplus_coupling_is_stored(tmp_path):
    text = """<robot name="screw">
  <link name="base"/><link name="nut"/><link name="carriage"/>
  <joint name="nut_joint" type="continuous"><parent link="base"/><child link="nut"/><axis xyz="0 0 1"/></joint>
  <joint name="stroke" type="prismatic"><parent link="base"/><child link="carriage"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.1" effort="1" velocity="1"/></joint>
  <constraint name="lead_screw" type="coupling"><predecessor link="nut"/><successor link="carriage"/>
    <ratio value="0.000795774715"/></constraint>
</robot>"""
    loops = load(tmp_path, text).loops
    assert loops.closures == [] and loops.n_rows == 0
    (coupling,) = loops.couplings
    assert (coupling.name, coupling.predecessor_joint, coupling.successor_joint) == \
        ("lead_screw", "nut_joint", "stroke")
    assert coupling.ratio == pytest.approx(0.005 / (2 * np.pi), rel=1e-9)


def test_urdfplus_coupling_is_enforced_and_its_ratio_calibrated(tmp_path):
    """Without <actuated>, the coupling's successor follows: q_stroke = ratio * q_nut, read from the nut."""
    text = """<robot name="screw">
  <link name="base"/><link name="nut"/><link name="carriage"/>
  <joint name="nut_joint" type="revolute"><parent link="base"/><child link="nut"/><axis xyz="0 0 1"/>
    <limit lower="-100" upper="100" effort="1" velocity="1"/></joint>
  <joint name="stroke" type="prismatic"><parent link="base"/><child link="carriage"/><axis xyz="0 0 1"/>
    <origin xyz="0.1 0 0" rpy="0 0.3 0"/><limit lower="0" upper="0.1" effort="1" velocity="1"/></joint>
  <constraint name="lead_screw" type="coupling"><predecessor link="nut"/><successor link="carriage"/>
    <ratio value="0.000795774715"/></constraint>
</robot>"""
    robot = load(tmp_path, text)
    assert robot.loops.actuated == ["nut_joint"]
    params = ParameterSet([Parameter("lead_screw.ratio", "transmission", "lead_screw", value=0.0008)])
    ms = ModelState(robot, params, ["nut_joint"])
    s = ms.sample(np.array([12.5]))
    assert s.q[robot.model.joints[robot.joint_id("stroke")].idx_q] == pytest.approx(0.0008 * 12.5, rel=1e-12)
    assert_frame_jacobians(robot, params, ["nut_joint"], np.array([12.5]), "carriage")


@pytest.mark.parametrize("bad, field", [
    (DRAKE.replace('link2 link="rocker_link"', 'link2 link="nowhere"'), "link"),
    (DRAKE.replace('type="revolute"><axis', 'type="helical"><axis'), "type"),
    (DRAKE.replace('<actuated joints="crank"/>', ""), "actuated"),
    (DRAKE.replace('joints="crank"', 'joints="crank_typo"'), "actuated"),
    (DRAKE.replace('xyz="0.25 0 0"/>', 'xyz="0.25 zero 0"/>'), "xyz"),
    (DRAKE.replace('type="revolute"><axis xyz="0 0 1"/>', 'type="distance">'), "length"),
    (DRAKE.replace('<loop_joint name="pin"', '<loop_joint'), "name"),
], ids=["unknown_link", "unknown_type", "no_actuated", "unknown_actuated", "bad_number", "no_length", "no_name"])
def test_bad_closures_raise_input_error_with_location(tmp_path, bad, field):
    with pytest.raises(InputError) as info:
        load(tmp_path, bad, "bad.urdf")
    assert info.value.field == field
    assert "bad.urdf" in str(info.value)


def test_underdetermined_mechanism_is_refused(tmp_path):
    text = DRAKE.replace('type="revolute"><axis xyz="0 0 1"/>', 'type="distance" length="0.25">') \
                .replace('<actuated joints="crank"/>', '<actuated joints="rocker"/>')
    with pytest.raises(InputError, match="do not determine"):
        load(tmp_path, text)
