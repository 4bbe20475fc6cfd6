"""Standard (distal) Denavit-Hartenberg table -> URDF, and the DH forward kinematics to check it.

Row i gives T_i(q_i) = Rot_z(q_i + theta_offset_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i); the arm is
T_1 ... T_n. A URDF joint turns about its own z axis after its origin, so joint i's origin is the
previous row's distal part Trans_x(a_{i-1}) Rot_x(alpha_{i-1}) times Rot_z(theta_offset_i) Trans_z(d_i)
(Rot_z commutes with the joint's own rotation and with Trans_z). The last row's distal part becomes a
fixed joint to the end link, which is then exactly DH frame n; link_i sits on joint i's axis
(DH frame i = link_i * Trans_x(a_i) Rot_x(alpha_i)). Lengths in metres, angles in radians.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.errors import InputError
from robocal.io.text_files import format_numbers, write_atomic


@dataclass(frozen=True)
class DHRow:
    a: float
    alpha: float
    d: float
    theta_offset: float = 0.0
    lower: float = -np.pi        # joint limits in the reading's coordinates (q, not q + theta_offset)
    upper: float = np.pi


def _rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    if axis == "x":
        return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def proximal(row: DHRow) -> pin.SE3:
    """Rot_z(theta_offset) Trans_z(d): the part of the row before the joint's own rotation."""
    return pin.SE3(_rot("z", row.theta_offset), np.array([0.0, 0.0, row.d]))


def distal(row: DHRow) -> pin.SE3:
    """Trans_x(a) Rot_x(alpha): the part of the row after it."""
    return pin.SE3(_rot("x", row.alpha), np.array([row.a, 0.0, 0.0]))


def dh_transform(row: DHRow, q: float) -> pin.SE3:
    """T_i(q) = Rot_z(q + theta_offset) Trans_z(d) Trans_x(a) Rot_x(alpha)."""
    return pin.SE3(_rot("z", q), np.zeros(3)) * proximal(row) * distal(row)


def dh_forward(rows: list[DHRow], q) -> pin.SE3:
    """T_1(q_1) ... T_n(q_n), the end (DH frame n) in the base (DH frame 0)."""
    q = np.asarray(q, dtype=float).reshape(-1)
    if len(q) != len(rows):
        raise InputError(f"{len(q)} joint values for a {len(rows)}-row DH table", field="q")
    M = pin.SE3.Identity()
    for row, qi in zip(rows, q):
        M = M * dh_transform(row, qi)
    return M


def _origin(parent, M: pin.SE3) -> None:
    etree.SubElement(parent, "origin", xyz=format_numbers(M.translation), rpy=format_numbers(pin.rpy.matrixToRpy(M.rotation)))


def dh_urdf(rows: list[DHRow], name: str, end_link: str = "flange", joint_prefix: str = "joint_",
            link_prefix: str = "link_", base_link: str = "base_link", note: str = "") -> str:
    """URDF text of a revolute chain from a DH table. Joints `<joint_prefix>1..n`, end link = DH frame n."""
    if not rows:
        raise InputError("empty DH table", field="rows")
    for i, r in enumerate(rows, 1):
        vals = (r.a, r.alpha, r.d, r.theta_offset, r.lower, r.upper)
        if not all(np.isfinite(vals)):
            raise InputError("DH values must be finite numbers", row=i, field="dh")
        if r.lower >= r.upper:
            raise InputError(f"lower limit {r.lower} is not below upper limit {r.upper}", row=i, field="limits")
    robot = etree.Element("robot", name=name)
    if note:
        robot.append(etree.Comment(f" {note} "))
    links = [base_link] + [f"{link_prefix}{i}" for i in range(1, len(rows) + 1)]
    for link in links + [end_link]:
        etree.SubElement(robot, "link", name=link)
    before = pin.SE3.Identity()
    for i, row in enumerate(rows, 1):
        j = etree.SubElement(robot, "joint", name=f"{joint_prefix}{i}", type="revolute")
        _origin(j, before * proximal(row))
        etree.SubElement(j, "parent", link=links[i - 1])
        etree.SubElement(j, "child", link=links[i])
        etree.SubElement(j, "axis", xyz="0 0 1")
        etree.SubElement(j, "limit", lower=format_numbers([row.lower]), upper=format_numbers([row.upper]), effort="0", velocity="1")
        before = distal(row)
    j = etree.SubElement(robot, "joint", name=f"{links[-1]}-{end_link}", type="fixed")
    _origin(j, before)
    etree.SubElement(j, "parent", link=links[-1])
    etree.SubElement(j, "child", link=end_link)
    return etree.tostring(robot, pretty_print=True, xml_declaration=True, encoding="utf-8").decode("utf-8")


def write_dh_urdf(rows: list[DHRow], path: str | Path, name: str, **kwargs) -> Path:
    return write_atomic(path, dh_urdf(rows, name, **kwargs))


DEG = np.pi / 180.0
# ABB IRB1600-x/1.45: DH reconstructed (docs/laser_psd.md) from the ROS-Industrial
# abb_irb1600_support description (J2 at 150 / 486.5 mm, upper arm 700, forearm 300 + 300, flange 65 mm);
# limits are the ROS-Industrial ones (with all joint signs +1 the DH q equals the URDF q).
IRB1600_145 = [
    DHRow(0.150, -90 * DEG, 0.4865, 0.0, -np.pi, np.pi),
    DHRow(0.700, 0.0, 0.0, -90 * DEG, -np.pi / 2, 2.0944),
    DHRow(0.0, -90 * DEG, 0.0, 0.0, -4.27601, 1.1344),
    DHRow(0.0, 90 * DEG, 0.600, 0.0, -3.4906, 3.4906),
    DHRow(0.0, -90 * DEG, 0.0, 0.0, -2.0071, 2.0071),
    DHRow(0.0, 0.0, 0.065, 180 * DEG, -6.9813, 6.9813),
]
IRB1600_NOTE = ("ABB IRB1600-x/1.45 built from its standard DH table (docs/laser_psd.md) by "
                "robocal.model.dh_urdf. tool0 is DH frame 6 (z out of the flange), as ROS-Industrial's "
                "tool0. Do not edit by hand; regenerate with write_dh_urdf(IRB1600_145, ...).")


def irb1600_urdf() -> str:
    return dh_urdf(IRB1600_145, "abb_irb1600_145", end_link="tool0", note=IRB1600_NOTE)
