"""Calibrated URDF: reloading it reproduces the calibrated model; everything else is kept as it was."""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from lxml import etree

from robocal import load_example, load_urdf
from robocal.errors import InputError
from robocal.model.urdf_export import calibrated_urdf, export_urdf
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters
from robocal.design.simulate import perturb, random_configurations

TIAGO = Path(__file__).parents[1] / "examples" / "tiago_mocap" / "data" / "tiago_48_schunk.urdf"


def _check_reload(robot, params, joints, tmp_path, frames):
    path = export_urdf(robot, params, tmp_path / "calibrated.urdf")
    reloaded = load_urdf(path)
    ms = ModelState(robot, params, joints)
    data = reloaded.model.createData()
    worst = 0.0
    for q_read in random_configurations(robot, joints, 20, np.random.default_rng(1)):
        s = ms.sample(q_read)
        q = reloaded.configuration(joints, q_read)
        pin.framesForwardKinematics(reloaded.model, data, q)
        for f in frames:
            expected = ms.base.inverse() * s.pose(f)       # robot-root frame (the base is not robot geometry)
            got = data.oMf[reloaded.frame_id(f)]
            worst = max(worst, np.abs(pin.log6(expected.inverse() * got).vector).max())
    return worst


def test_ur5_reload_reproduces_calibrated_frames(tmp_path):
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True})
    truth = perturb(params, np.random.default_rng(0), 5e-3, 0.05)
    frames = [f.name for f in robot.model.frames if f.type == pin.FrameType.BODY]
    assert _check_reload(robot, truth, joints, tmp_path, frames) < 1e-9


def test_tiago_export_keeps_every_other_element(tmp_path):
    robot = load_urdf(TIAGO)
    joints = robot.supporting_joints("wrist_ft_tool_link")
    params = robot_parameters(robot, joints, "full", frames={"wrist_ft_tool_link": True})
    truth = perturb(params, np.random.default_rng(2), 2e-3, 0.01)
    out = export_urdf(robot, truth, tmp_path / "tiago_calibrated.urdf")
    before, after = etree.parse(str(TIAGO)).getroot(), etree.parse(str(out)).getroot()
    tags = lambda root: sorted(e.tag if isinstance(e.tag, str) else "comment" for e in root.iter())
    assert tags(before) == tags(after)
    assert len(before.findall("transmission")) == len(after.findall("transmission")) > 0
    assert len(before.findall("gazebo")) == len(after.findall("gazebo")) > 0
    changed = {el.getparent().get("name") for el_b, el in zip(before.iter("origin"), after.iter("origin"))
               if el_b.attrib != el.attrib}
    assert changed == set(joints) | {"wrist_tool_joint"}   # the fixed joint that creates wrist_ft_tool_link
    frames = [f.name for f in robot.model.frames if f.type == pin.FrameType.BODY]
    assert _check_reload(robot, truth, joints, tmp_path, frames) < 1e-9


def test_input_urdf_is_never_overwritten(tmp_path):
    src = tmp_path / "arm.urdf"
    src.write_text(load_example("ur5").urdf_text)
    robot = load_urdf(src)
    params = robot_parameters(robot, robot.joint_names, "offsets")
    params["elbow_joint.offset"].value = 0.01
    original = src.read_bytes()
    with pytest.raises(InputError, match="refusing to overwrite the input URDF"):
        export_urdf(robot, params, src)
    assert src.read_bytes() == original


def test_offsets_fold_into_the_origin_about_the_axis():
    robot = load_example("ur5")
    params = robot_parameters(robot, robot.joint_names, "offsets")
    params["elbow_joint.offset"].value = 0.1
    root = etree.fromstring(calibrated_urdf(robot, params))
    j = next(e for e in root.iter("joint") if e.get("name") == "elbow_joint")
    orig = next(e for e in etree.fromstring(robot.urdf_text.encode()).iter("joint") if e.get("name") == "elbow_joint")
    # the elbow turns about y: pitch grows by the offset, the translation is unchanged
    assert j.find("origin").get("xyz").split() and np.allclose(
        [float(v) for v in j.find("origin").get("xyz").split()], [float(v) for v in orig.find("origin").get("xyz").split()])
    assert np.isclose(float(j.find("origin").get("rpy").split()[1]) - float(orig.find("origin").get("rpy").split()[1]), 0.1)
    assert j.find("axis").get("xyz") == orig.find("axis").get("xyz")
