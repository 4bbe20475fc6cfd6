"""Calibrated closure elements of a closed-chain URDF: loop anchors and screw transmissions.

A loop anchor `<closure>.link1|link2` is a frame robocal adds from the closure element, so its
calibrated placement goes back into that element: Drake's `<loop_joint>` `<link1|link2 xyz rpy>`, or the
URDF+ `<predecessor|successor>` `<origin>`. A screw transmission's calibrated lead goes into `lead`
(and `pitch` = lead / starts), keeping in `nominal_lead` the lead the controller converts the encoder
with; a changed thread hand rewrites `sigma` (and `hand`).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.io.text_files import format_number, format_numbers
from robocal.model.parameters import ParameterSet

_ANCHOR_TAGS = {"loop_joint": ("link1", "link2"), "loop": ("predecessor", "successor"),
                "constraint": ("predecessor", "successor")}


def _anchor_element(root, closure: str, end: int):
    for tag, children in _ANCHOR_TAGS.items():
        for el in root.findall(tag):
            if el.get("name") == closure:
                child = el.find(children[end])
                return child if tag == "loop_joint" else _origin_of(child)
    return None


def _origin_of(child):
    org = child.find("origin")
    if org is None:
        org = etree.SubElement(child, "origin")
    return org


def edit_closure_elements(root, params: ParameterSet) -> None:
    """Write calibrated loop anchors and transmission values into the URDF tree `root` (in place)."""
    for target in {p.target for p in params if p.kind == "frame_placement"}:
        closure, _, end = target.rpartition(".")
        if end not in ("link1", "link2"):
            continue
        el = _anchor_element(root, closure, 0 if end == "link1" else 1)
        delta = params.placement_vector("frame_placement", target)
        if el is None or not delta.any():
            continue
        xyz = np.array((el.get("xyz") or "0 0 0").split(), dtype=float)
        rpy = np.array((el.get("rpy") or "0 0 0").split(), dtype=float)
        M = pin.SE3(pin.rpy.rpyToMatrix(*rpy), xyz) * pin.exp6(pin.Motion(delta))
        el.set("xyz", format_numbers(M.translation))
        el.set("rpy", format_numbers(pin.rpy.matrixToRpy(M.rotation)))
    screws = {s.get("name"): s for s in root.findall("screw_transmission")}
    for p in params:
        if p.kind != "transmission" or p.target not in screws:
            continue
        el, component = screws[p.target], p.name.rsplit(".", 1)[-1]
        if component == "lead" and p.value != float(el.get("lead")):
            el.set("nominal_lead", el.get("nominal_lead", el.get("lead")))
            el.set("lead", format_number(p.value))
            if el.get("starts"):
                el.set("pitch", format_number(p.value / int(el.get('starts'))))
        elif component == "hand" and int(p.value) != int(el.get("sigma")):
            el.set("sigma", str(int(p.value)))
            if el.get("hand") in ("right", "left"):
                el.set("hand", {"right": "left", "left": "right"}[el.get("hand")])


def driven_offset_scales(robot, params: ParameterSet) -> dict[str, float]:
    """{joint: s} for joints driven through a screw: the reading's offset moves the joint by s = L / L0."""
    if robot.loops is None:
        return {}
    leads = {p.target: p.value for p in params if p.kind == "transmission" and p.name.endswith(".lead")}
    return {r.driven: leads.get(r.name, r.lead) / r.nominal_lead
            for r in robot.loops.relations if r.driven is not None}
