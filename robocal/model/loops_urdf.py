"""Reading loop closures, couplings and the actuated joints of a closed chain from URDF (lxml).

A closed chain is its URDF spanning tree (loaded by Pinocchio) plus closure elements that URDF
readers ignore. Two conventions are read:

* robocal's written format, Drake's legacy ``<loop_joint>``::

    <loop_joint name="leg1_top" type="spherical|fixed|distance|revolute" [length="0.3"]>
      <link1 link="leg1_rod" xyz="0 0 0" rpy="0 0 0"/>
      <link2 link="platform" xyz="0.2 0.05 0" rpy="0 0 0"/>
      [<axis xyz="0 0 1"/>]            <!-- revolute only, in the link1 anchor frame -->
    </loop_joint>

* URDF+ (arXiv 2411.19753): ``<loop>`` (or ``<constraint>``) naming a predecessor and a successor
  link, each with an optional ``<origin>``; type fixed, revolute/continuous (``<axis>``) and, as a
  robocal extension, spherical. ``<coupling>`` (or ``<constraint type="coupling">``) with
  ``<ratio value>``: a gear or screw ties two joints.

* robocal's ``<screw_transmission>`` (a ball screw whose nut may roll; see robocal.model.joint_relations).

Couplings and screw transmissions are joint relations: one linear row each, assembled with the closures.

plus ``<actuated joints="j1 j2 ..."/>`` (or, failing that, the joints of ``<transmission>``
elements). Each closure k is anchored on two Pinocchio frames ``<name>.link1`` and ``<name>.link2``
that are added to ``robot.model``; moving a loop anchor is therefore a frame-placement edit.
Closure kinds and their rows: robocal.model.loop_rows.
"""
from __future__ import annotations

import logging

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.model.joint_relations import Coupling, ScrewTransmission
from robocal.model.loop_rows import ROWS, Closure
from robocal.model.loops import loop_set

log = logging.getLogger(__name__)

# closure `type` attribute -> kind, per convention
DRAKE_KINDS = {"spherical": "point", "ball": "point", "fixed": "frame", "distance": "distance",
                "revolute": "revolute", "continuous": "revolute"}
URDFPLUS_KINDS = {"spherical": "point", "ball": "point", "fixed": "frame",
                   "revolute": "revolute", "continuous": "revolute"}


def _floats(element, attr: str, n: int, default: str, source: str) -> np.ndarray:
    text = element.get(attr, default)
    try:
        values = np.array([float(x) for x in text.split()])
    except ValueError:
        values = np.zeros(0)
    if values.size != n or not np.all(np.isfinite(values)):
        raise InputError(f"<{element.tag}> attribute '{attr}' must hold {n} numbers, got '{text}'",
                         source=source, row=element.sourceline, field=attr)
    return values


def _placement(element, source: str) -> pin.SE3:
    """SE3 from xyz/rpy attributes (URDF convention) of `element`, identity when absent."""
    if element is None:
        return pin.SE3.Identity()
    xyz = _floats(element, "xyz", 3, "0 0 0", source)
    rpy = _floats(element, "rpy", 3, "0 0 0", source)
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), xyz)


def _child(element, tag: str, source: str):
    child = element.find(tag)
    if child is None or not child.get("link"):
        raise InputError(f"closure '{element.get('name')}' needs a <{tag} link=\"...\"> element",
                         source=source, row=element.sourceline, field=tag)
    return child


def _axis(element, source: str) -> tuple:
    node = element.find("axis")
    a = np.array([1.0, 0.0, 0.0]) if node is None else _floats(node, "xyz", 3, "1 0 0", source)
    n = np.linalg.norm(a)
    if n == 0:
        raise InputError("closure axis must not be zero", source=source, row=element.sourceline, field="axis")
    return tuple(a / n)


def _read_closure(robot, element, source):
    """(name, kind, link1, placement1, link2, placement2, length, axis) of one closure element."""
    name = element.get("name")
    if not name:
        raise InputError(f"<{element.tag}> without a name", source=source, row=element.sourceline, field="name")
    type_ = (element.get("type") or "").lower()
    drake = element.tag == "loop_joint"
    kinds = DRAKE_KINDS if drake else URDFPLUS_KINDS
    if type_ not in kinds:
        raise InputError(f"closure '{name}' has type '{type_}'; robocal reads "
                         f"{', '.join(sorted(kinds))}", source=source, row=element.sourceline, field="type")
    kind = kinds[type_]
    if drake:
        e1, e2 = _child(element, "link1", source), _child(element, "link2", source)
        m1, m2 = _placement(e1, source), _placement(e2, source)
    else:
        e1, e2 = _child(element, "predecessor", source), _child(element, "successor", source)
        m1, m2 = _placement(e1.find("origin"), source), _placement(e2.find("origin"), source)
    length = 0.0
    if kind == "distance":
        if element.get("length") is None:
            raise InputError(f"distance closure '{name}' needs a length attribute (m)", source=source,
                             row=element.sourceline, field="length")
        length = float(_floats(element, "length", 1, "", source)[0])
    axis = _axis(element, source) if kind == "revolute" else None
    for e in (e1, e2):
        if not robot.model.existBodyName(e.get("link")):
            raise InputError(f"closure '{name}' names an unknown link '{e.get('link')}'", source=source,
                             row=e.sourceline, field="link")
    return name, kind, e1.get("link"), m1, e2.get("link"), m2, length, axis


def _joint_of_link(robot, link: str, element, source) -> str:
    fid = robot.model.getFrameId(link, pin.FrameType.BODY)
    if fid >= len(robot.model.frames):
        raise InputError(f"coupling '{element.get('name')}' names an unknown link '{link}'",
                         source=source, row=element.sourceline, field="link")
    return robot.model.names[robot.model.frames[fid].parentJoint]


def _read_coupling(robot, element, source) -> Coupling:
    name = element.get("name", "")
    pred = _child(element, "predecessor", source).get("link")
    succ = _child(element, "successor", source).get("link")
    ratio_node = element.find("ratio")
    ratio = 1.0 if ratio_node is None else float(_floats(ratio_node, "value", 1, "1", source)[0])
    return Coupling(name, _joint_of_link(robot, pred, element, source),
                    _joint_of_link(robot, succ, element, source), ratio)


def _read_screw(robot, element, source) -> ScrewTransmission:
    """robocal's <screw_transmission name stroke_joint roll_joint lead sigma [nominal_lead gear_ratio]>."""
    name = element.get("name") or ""
    joints = []
    for attr in ("stroke_joint", "roll_joint"):
        j = element.get(attr)
        if not j or not robot.model.existJointName(j):
            raise InputError(f"screw_transmission '{name}': {attr} '{j}' is not a joint of the model",
                             source=source, row=element.sourceline, field=attr)
        if robot.model.joints[robot.model.getJointId(j)].nq != 1:
            raise InputError(f"screw_transmission '{name}': {attr} '{j}' must be a 1-dof revolute or prismatic "
                             "joint (not continuous)", source=source, row=element.sourceline, field=attr)
        joints.append(j)
    lead = float(_floats(element, "lead", 1, "", source)[0])
    nominal = float(_floats(element, "nominal_lead", 1, str(lead), source)[0])
    sigma = float(_floats(element, "sigma", 1, "", source)[0])
    if lead <= 0 or nominal <= 0 or sigma not in (-1.0, 1.0):
        raise InputError(f"screw_transmission '{name}': lead and nominal_lead must be > 0 and sigma +1 or -1",
                         source=source, row=element.sourceline, field="lead" if sigma in (-1.0, 1.0) else "sigma")
    gear = float(_floats(element, "gear_ratio", 1, "1", source)[0])
    return ScrewTransmission(name, joints[0], joints[1], lead, int(sigma), nominal, gear)


def _read_actuated(robot, tree, source, required: bool) -> list[str]:
    nodes = tree.findall("actuated")
    if len(nodes) > 1:
        raise InputError("more than one <actuated> element", source=source, row=nodes[1].sourceline)
    if nodes:
        names = nodes[0].get("joints", "").split()
        row = nodes[0].sourceline
    else:  # fall back on standard <transmission> elements
        names = [j.get("name") for t in tree.findall("transmission") for j in t.findall("joint")]
        row = None
    if not names and required:
        raise InputError("a closed-chain URDF needs <actuated joints=\"j1 j2 ...\"/> (or <transmission> "
                         "elements) naming the joints read by encoders", source=source, field="actuated")
    for n in names:
        if not robot.model.existJointName(n):
            raise InputError(f"actuated joint '{n}' is not a joint of the model", source=source, row=row,
                             field="actuated")
        j = robot.model.joints[robot.model.getJointId(n)]
        if j.nv != 1:
            raise InputError(f"actuated joint '{n}' must have one degree of freedom", source=source, row=row,
                             field="actuated")
    if len(set(names)) != len(names):
        raise InputError("an actuated joint is listed twice", source=source, row=row, field="actuated")
    return names


def read_loops(robot, tree):
    """Read the closures of a URDF (lxml root element) into a LoopSet; None for a tree robot.

    Adds the anchor frames `<closure>.link1` / `<closure>.link2` to robot.model.
    """
    source = str(robot.urdf_path) if robot.urdf_path else "URDF"
    closures_xml = tree.findall("loop_joint") + tree.findall("loop") + [
        e for e in tree.findall("constraint") if (e.get("type") or "").lower() != "coupling"]
    couplings_xml = tree.findall("coupling") + [
        e for e in tree.findall("constraint") if (e.get("type") or "").lower() == "coupling"]
    screws_xml = tree.findall("screw_transmission")
    if not closures_xml and not couplings_xml and not screws_xml:
        return None
    closures, seen = [], set()
    for element in closures_xml:
        name, kind, link1, m1, link2, m2, length, axis = _read_closure(robot, element, source)
        if name in seen:
            raise InputError(f"closure '{name}' is defined twice", source=source, row=element.sourceline,
                             field="name")
        seen.add(name)
        f1, f2 = f"{name}.link1", f"{name}.link2"
        robot.add_frame(f1, parent=link1, placement=m1)
        robot.add_frame(f2, parent=link2, placement=m2)
        closures.append(Closure(name, kind, f1, f2, ROWS[kind], length, axis))
    relations = [_read_coupling(robot, e, source) for e in couplings_xml]
    relations += [_read_screw(robot, e, source) for e in screws_xml]
    names = [r.name for r in relations]
    if len(set(names)) != len(names):
        raise InputError("two couplings or screw transmissions share a name", source=source, field="name")
    actuated = _read_actuated(robot, tree, source, bool(closures))
    if not actuated and not closures:   # joints tied by couplings only: the successors follow the rest
        followers = {r.successor_joint for r in relations if r.kind == "coupling"}
        actuated = [robot.model.names[j] for j in range(1, robot.model.njoints)
                    if robot.model.joints[j].nv == 1 and robot.model.names[j] not in followers]
    loops = loop_set(robot, closures, actuated, relations, source)
    log.info("read %d closures (%d rows), %d actuated joints, %d joint relations", len(closures), loops.n_rows,
             len(loops.actuated), len(relations))
    return loops
