"""Calibrated URDF: the input file with only the changed <origin> elements edited.

A joint's placement error and zero offset are folded into its origin (origin * exp6(delta), then the
offset as a motion along the joint axis, which leaves the axis as written); a calibrated frame that
is a URDF link edits the origin of the fixed joint that creates it; loop anchors and screw transmissions
edit their closure elements (export_loops). Everything else (transmissions,
gazebo tags, meshes, comments) is kept byte for byte by lxml. Frames robocal added itself (markers,
tools declared in the config) and the measurement-frame (base) parameters are not robot geometry:
they stay in the JSON result. The file is written atomically and never over the input URDF.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.errors import InputError
from robocal.io.text_files import format_numbers, write_atomic
from robocal.model.urdf_export_loops import driven_offset_scales, edit_closure_elements
from robocal.model.parameters import ParameterSet


def _origin(joint_el) -> tuple[etree._Element, pin.SE3]:
    org = joint_el.find("origin")
    if org is None:
        org = etree.Element("origin")
        joint_el.insert(0, org)
    xyz = np.array([float(v) for v in (org.get("xyz") or "0 0 0").split()])
    rpy = np.array([float(v) for v in (org.get("rpy") or "0 0 0").split()])
    return org, pin.SE3(pin.rpy.rpyToMatrix(*rpy), xyz)


def _write_origin(org, M: pin.SE3) -> None:
    org.set("xyz", format_numbers(M.translation))
    org.set("rpy", format_numbers(pin.rpy.matrixToRpy(M.rotation)))


def _axis_motion(joint_el, offset: float) -> pin.SE3:
    ax = joint_el.find("axis")
    axis = np.array([float(v) for v in (ax.get("xyz") if ax is not None else "1 0 0").split()])
    axis /= np.linalg.norm(axis)
    if joint_el.get("type") == "prismatic":
        return pin.SE3(np.eye(3), axis * offset)
    return pin.SE3(pin.exp3(axis * offset), np.zeros(3))


def calibrated_urdf(robot, params: ParameterSet) -> bytes:
    """The calibrated URDF document as bytes."""
    if not robot.urdf_text:
        raise InputError("this robot was not loaded from a URDF; nothing to export")
    root = etree.fromstring(robot.urdf_text.encode("utf-8"))
    # direct children only: <transmission> elements hold <joint> references of their own
    joints = {j.get("name"): j for j in root.findall("joint")}
    by_child = {j.find("child").get("link"): j for j in joints.values() if j.find("child") is not None}
    scales = driven_offset_scales(robot, params)
    offsets = {p.target: p.value * scales.get(p.target, 1.0) for p in params if p.kind == "joint_offset"}
    targets = {p.target for p in params if p.kind == "joint_placement"} | set(offsets)
    for name in targets:
        el = joints[name]
        delta = params.placement_vector("joint_placement", name)
        off = offsets.get(name, 0.0)
        if (delta is None or not delta.any()) and off == 0.0:
            continue
        org, O = _origin(el)
        if delta is not None:
            O = O * pin.exp6(pin.Motion(delta))
        _write_origin(org, O * _axis_motion(el, off))
    for target in {p.target for p in params if p.kind == "frame_placement"}:
        delta = params.placement_vector("frame_placement", target)
        frame = robot.model.frames[robot.frame_id(target)]
        if frame.type == pin.FrameType.BODY and target in by_child:
            el = by_child[target]
        elif frame.type == pin.FrameType.FIXED_JOINT and target in joints:
            el = joints[target]
        else:
            continue  # a frame robocal added: reported in the JSON, not part of the URDF
        if not delta.any():
            continue
        org, O = _origin(el)
        _write_origin(org, O * pin.exp6(pin.Motion(delta)))
    edit_closure_elements(root, params)
    return etree.tostring(root, xml_declaration=True, encoding="utf-8")


def export_urdf(robot, params: ParameterSet, path: str | Path) -> Path:
    """Write the calibrated URDF to `path` (refuses to overwrite the robot's input URDF)."""
    path = Path(path).resolve()
    if robot.urdf_path is not None and path == Path(robot.urdf_path).resolve():
        raise InputError("refusing to overwrite the input URDF; choose another file name", source=str(path))
    write_atomic(path, calibrated_urdf(robot, params))
    return path
