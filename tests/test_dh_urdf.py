"""DH table -> URDF: Pinocchio's frames equal the DH product; the IRB1600 matches its published chain."""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from robocal.errors import InputError
from robocal.model.dh_urdf import DEG, IRB1600_145, DHRow, dh_forward, distal, dh_urdf, irb1600_urdf
from robocal.model.robot import load_urdf
from robocal.testing import assert_same_text_and_numbers

ROOT = Path(__file__).resolve().parents[1]
UR5_DH = [DHRow(0.0, 90 * DEG, 0.089159), DHRow(-0.425, 0.0, 0.0), DHRow(-0.39225, 0.0, 0.0),
          DHRow(0.0, 90 * DEG, 0.10915), DHRow(0.0, -90 * DEG, 0.09465), DHRow(0.0, 0.0, 0.0823)]

# The ROS-Industrial abb_irb1600_support chain (irb1600_x_145 macro), transcribed from its published
# joint origins and axes: an independent description of the same arm.
ROSI_IRB1600 = """<robot name="rosi">
  <link name="base_link"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="l4"/>
  <link name="l5"/><link name="l6"/><link name="tool0"/>
  <joint name="j1" type="revolute"><origin xyz="0 0 0"/><parent link="base_link"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-3.14" upper="3.14" effort="0" velocity="1"/></joint>
  <joint name="j2" type="revolute"><origin xyz="0.15 0 0.4865"/><parent link="l1"/><child link="l2"/>
    <axis xyz="0 1 0"/><limit lower="-3.14" upper="3.14" effort="0" velocity="1"/></joint>
  <joint name="j3" type="revolute"><origin xyz="0 0 0.700"/><parent link="l2"/><child link="l3"/>
    <axis xyz="0 1 0"/><limit lower="-3.14" upper="3.14" effort="0" velocity="1"/></joint>
  <joint name="j4" type="revolute"><origin xyz="0.300 0 0"/><parent link="l3"/><child link="l4"/>
    <axis xyz="1 0 0"/><limit lower="-3.14" upper="3.14" effort="0" velocity="1"/></joint>
  <joint name="j5" type="revolute"><origin xyz="0.300 0 0"/><parent link="l4"/><child link="l5"/>
    <axis xyz="0 1 0"/><limit lower="-3.14" upper="3.14" effort="0" velocity="1"/></joint>
  <joint name="j6" type="revolute"><origin xyz="0.065 0 0"/><parent link="l5"/><child link="l6"/>
    <axis xyz="1 0 0"/><limit lower="-3.14" upper="3.14" effort="0" velocity="1"/></joint>
  <joint name="t" type="fixed"><origin xyz="0 0 0" rpy="0 1.5707963267948966 0"/><parent link="l6"/>
    <child link="tool0"/></joint>
</robot>"""


def _frame_pose(model, q, frame):
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId(frame)]


@pytest.mark.parametrize("rows,end", [(IRB1600_145, "tool0"), (UR5_DH, "flange")])
def test_urdf_frames_equal_dh_forward_kinematics(rows, end, tmp_path):
    text = irb1600_urdf() if rows is IRB1600_145 else dh_urdf(rows, "ur5_dh")
    path = tmp_path / "arm.urdf"
    path.write_text(text)
    model = load_urdf(path).model
    rng = np.random.default_rng(11)
    worst = 0.0
    for q in rng.uniform(-np.pi, np.pi, (50, len(rows))):
        # every intermediate frame too: link_i sits on joint i's axis, so DH frame i = link_i * distal_i
        for i in range(1, len(rows) + 1):
            M = _frame_pose(model, q, f"link_{i}") * distal(rows[i - 1])
            worst = max(worst, np.abs(M.homogeneous - dh_forward(rows[:i], q[:i]).homogeneous).max())
        M = _frame_pose(model, q, end)
        worst = max(worst, np.abs(M.homogeneous - dh_forward(rows, q).homogeneous).max())
    assert worst < 1e-12


def test_irb1600_matches_the_ros_industrial_chain_and_published_dimensions():
    dh = load_urdf(ROOT / "urdf" / "abb_irb1600.urdf").model
    rosi = pin.buildModelFromXML(ROSI_IRB1600)
    rng = np.random.default_rng(12)
    for q in rng.uniform(-np.pi, np.pi, (50, 6)):
        a, b = _frame_pose(dh, q, "tool0"), _frame_pose(rosi, q, "tool0")
        assert np.abs(a.homogeneous - b.homogeneous).max() < 1e-9
    home = _frame_pose(dh, np.zeros(6), "tool0")
    # published: wrist centre 150 + 600 mm out, 486.5 + 700 mm up; flange 65 mm beyond, facing +x
    assert np.allclose(home.translation, [0.815, 0.0, 1.1865], atol=1e-12)
    assert np.allclose(home.rotation[:, 2], [1.0, 0.0, 0.0], atol=1e-12)


def test_committed_irb1600_urdf_is_the_generator_output_and_has_the_published_limits():
    path = ROOT / "urdf" / "abb_irb1600.urdf"
    assert_same_text_and_numbers(path.read_text(), irb1600_urdf(), what=str(path))
    robot = load_urdf(path)
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    deg = np.degrees
    assert np.allclose(deg(lo), [-180, -90, -245, -200, -115, -400], atol=0.01)
    assert np.allclose(deg(hi), [180, 120, 65, 200, 115, 400], atol=0.01)


def test_bad_dh_rows_name_the_row_and_field():
    with pytest.raises(InputError) as e:
        dh_urdf([DHRow(0.1, 0.0, 0.0), DHRow(np.nan, 0.0, 0.0)], "bad")
    assert e.value.row == 2 and e.value.field == "dh"
    with pytest.raises(InputError) as e:
        dh_urdf([DHRow(0.1, 0.0, 0.0, lower=1.0, upper=-1.0)], "bad")
    assert e.value.row == 1 and e.value.field == "limits"
    with pytest.raises(InputError):
        dh_forward(IRB1600_145, np.zeros(5))
