"""A closed-chain robot from MJCF: Pinocchio 4.1 reads the tree and the equality constraints, robocal the rest.

`pin.buildModelAndConstraintsFromMJCF` gives the kinematic tree and one PointAnchorConstraintModel per
`<equality><connect>` and one FrameAnchorConstraintModel per `<weld>` (docs/closed_loops.md). What that reader
leaves out or drops without a word is checked here first, on the XML, so a bad file is named by line:

- an equality between bodies, sites or joints the file does not have (Pinocchio: "Model does not have any body
  named ...", no file or constraint), and equality kinds robocal cannot enforce (tendon, flex) or inactive ones;
- `<equality><joint>` (ignored by Pinocchio): read here as a robocal Coupling when linear, joint1 = r * joint2;
- a second body under `<worldbody>` (Pinocchio reads the first only) and `<include>` (not followed).

Equality `name`s (Pinocchio does not carry them) name the closures, default connect1, weld1, ...; anchors are
frames `<name>.link1/.link2` as for a URDF (robocal.model.constraint_models). The actuated joints are those of the
`<actuator>` elements (`joint=`), unless the caller names them. A free or ball joint's initial pose (MJCF writes it
as the body's pos/quat, Pinocchio keeps it in qpos0) is folded into its placement, so that the neutral
configuration is the pose the file draws, as a URDF floating joint's origin is.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.errors import InputError
from robocal.model.constraint_models import add_constraint_closures
from robocal.model.joint_relations import Coupling
from robocal.model.loops import loop_set
from robocal.model.robot import Robot
from robocal.model.urdf_check import c_stderr_captured

CLOSURE_TAGS = {"connect": "point", "weld": "frame"}


def _parse(path: Path):
    if not path.is_file():
        raise InputError("MJCF file not found", source=str(path))
    try:
        root = etree.parse(str(path), parser=etree.XMLParser(remove_comments=True)).getroot()
    except etree.XMLSyntaxError as exc:
        raise InputError(f"not valid XML at line {exc.lineno}: {exc.msg.splitlines()[0].strip()}",
                         source=str(path)) from None
    if root.tag != "mujoco":
        raise InputError(f"not an MJCF file: the root element (line {root.sourceline}) is <{root.tag}>, expected "
                         "<mujoco>", source=str(path))
    include = root.find(".//include")
    if include is not None:
        raise InputError(f"<include> at line {include.sourceline}: Pinocchio 4.1's MJCF reader does not follow "
                         "includes; write the included elements into this file", source=str(path), field="include")
    return root


def _names(root, source: str):
    """Body, site and joint names of the kinematic tree (not of <default> classes)."""
    bodies, sites, joints = set(), set(), set()
    for world in root.iter("worldbody"):
        top = [b for b in world if b.tag == "body"]
        if len(top) > 1:
            raise InputError(f"<worldbody> has {len(top)} bodies (line {top[1].sourceline} is the second); Pinocchio "
                             "4.1 reads only the first: put every body under one root body (a fixed base)",
                             source=source, row=top[1].sourceline, field="worldbody")
        bodies |= {b.get("name") for b in world.iter("body") if b.get("name")}
        sites |= {s.get("name") for s in world.iter("site") if s.get("name")}
        joints |= {j.get("name") for j in world.iter("joint", "freejoint") if j.get("name")}
    return bodies, sites, joints


def _equalities(root, bodies, sites, joints, source: str):
    """[(element, name)] of the equality constraints, checked against the tree's names."""
    out, count = [], {}
    for section in root.findall("equality"):
        for e in section:
            if not isinstance(e.tag, str):
                continue
            count[e.tag] = count.get(e.tag, 0) + 1
            name = e.get("name") or f"{e.tag}{count[e.tag]}"
            if e.tag not in (*CLOSURE_TAGS, "joint"):
                raise InputError(f"equality constraint '{name}' is a <{e.tag}>; robocal reads connect, weld and "
                                 "joint", source=source, row=e.sourceline, field=name)
            if e.get("active", "true").lower() in ("false", "0"):
                raise InputError(f"equality constraint '{name}' is inactive (active=\"{e.get('active')}\"); robocal "
                                 "enforces every loop it reads: remove it", source=source, row=e.sourceline, field=name)
            if e.tag == "joint":
                pairs = [("joint1", joints), ("joint2", joints)]
            elif e.get("site1") is not None or e.get("site2") is not None:
                pairs = [("site1", sites), ("site2", sites)]
            else:
                pairs = [("body1", bodies), ("body2", bodies)]
            for attr, known in pairs:
                value = e.get(attr)
                required = attr.endswith("1") or attr.startswith("site")
                if value is None and not required:
                    continue      # body2 / joint2 omitted: the world, or a constant
                if value not in known:
                    what = attr.rstrip("12")
                    raise InputError(f"equality constraint '{name}' (<{e.tag}>) names {what} '{value}' in {attr}, "
                                     f"which is not in the model", source=source, row=e.sourceline, field=attr)
            out.append((e, name))
    return out


def _coupling(e, name: str, source: str) -> Coupling:
    """<joint joint1 joint2 polycoef>: joint1 = c0 + c1 joint2 + ...; robocal's Coupling is the linear case."""
    try:
        coef = np.array([float(v) for v in (e.get("polycoef") or "0 1 0 0 0").split()] + [0.0] * 5)[:5]
    except ValueError:
        coef = np.full(5, np.nan)
    if e.get("joint2") is None or not np.all(np.isfinite(coef)) or coef[0] != 0.0 or np.any(coef[2:] != 0.0):
        raise InputError(f"joint equality '{name}': robocal reads joint1 = ratio * joint2 (polycoef=\"0 ratio 0 0 0\" "
                         f"and a joint2), got polycoef=\"{e.get('polycoef')}\"", source=source, row=e.sourceline,
                         field="polycoef")
    return Coupling(name, e.get("joint2"), e.get("joint1"), float(coef[1]))


def _fold_initial_poses(model: pin.Model) -> None:
    """Free and ball joints: their qpos0 into their placement, so that q = neutral is the pose the file draws."""
    ref = next((e.data() for e in model.referenceConfigurations if e.key() == "qpos0"), None)
    if ref is None:
        return
    for j in range(1, model.njoints):
        joint = model.joints[j]
        kind = joint.shortname()
        if kind == "JointModelFreeFlyer":
            model.jointPlacements[j] = model.jointPlacements[j] * pin.XYZQUATToSE3(ref[joint.idx_q:joint.idx_q + 7])
        elif kind == "JointModelSpherical":
            x, y, z, w = ref[joint.idx_q:joint.idx_q + 4]
            quat = pin.Quaternion(w, x, y, z)
            model.jointPlacements[j] = model.jointPlacements[j] * pin.SE3(quat.normalized().matrix(), np.zeros(3))
        else:
            continue
        ref[joint.idx_q:joint.idx_q + joint.nq] = pin.neutral(model)[joint.idx_q:joint.idx_q + joint.nq]
    model.referenceConfigurations["qpos0"] = ref


def _anchor_joint(model: pin.Model, e, side: int) -> int:
    """The joint Pinocchio anchors side `side` of a connect/weld on (0: the world)."""
    site, body = e.get(f"site{side}"), e.get(f"body{side}")
    if site is not None:
        return model.frames[model.getFrameId(site, pin.FrameType.OP_FRAME)].parentJoint
    if body is None:
        return 0
    return model.frames[model.getFrameId(body, pin.FrameType.BODY)].parentJoint


def _actuated_joints(root, joints, source: str) -> list[str]:
    out = []
    for section in root.findall("actuator"):
        for a in section:
            if isinstance(a.tag, str) and a.get("joint") is not None:
                if a.get("joint") not in joints:
                    raise InputError(f"actuator <{a.tag}> names joint '{a.get('joint')}', which is not in the model",
                                     source=source, row=a.sourceline, field="joint")
                out.append(a.get("joint"))
    return out


def load_mjcf(path: str | Path, actuated: list[str] | None = None, name: str | None = None) -> Robot:
    """A Robot from an MJCF file: its tree, its connect/weld equalities as loop closures (joint equalities as
    couplings), and its actuated joints (`actuated`, else the joints its <actuator> elements drive)."""
    path = Path(path).resolve()
    source = str(path)
    root = _parse(path)
    bodies, sites, joints = _names(root, source)
    equalities = _equalities(root, bodies, sites, joints, source)
    error = None
    with c_stderr_captured() as c_errors:
        try:
            model, points, frames = pin.buildModelAndConstraintsFromMJCF(source)
        except (RuntimeError, ValueError) as exc:
            error = exc
    if error is not None:
        detail = " ".join(line.strip() for line in "".join(c_errors).splitlines() if line.strip())
        raise InputError(f"Pinocchio cannot build a model from this MJCF: {error}" + (f" ({detail})" if detail else ""),
                         source=source) from None
    _fold_initial_poses(model)
    robot = Robot(model=model, mjcf_path=path, name=name or root.get("model") or path.stem)
    queues = {"connect": list(points), "weld": list(frames)}
    constraints, names, lines, relations = [], [], [], []
    for e, eq_name in equalities:
        if e.tag == "joint":
            relations.append(_coupling(e, eq_name, source))
            continue
        if not queues[e.tag]:
            raise InputError(f"Pinocchio returned fewer {e.tag} constraints than the file has; '{eq_name}' is "
                             "missing", source=source, row=e.sourceline, field=eq_name)
        cm = queues[e.tag].pop(0)
        if (cm.joint1_id, cm.joint2_id) != (_anchor_joint(model, e, 1), _anchor_joint(model, e, 2)):
            raise InputError(f"equality constraint '{eq_name}': Pinocchio anchored it on joints {cm.joint1_id} and "
                             f"{cm.joint2_id}, not on those of the bodies it names", source=source, row=e.sourceline,
                             field=eq_name)
        constraints.append(cm)
        names.append(eq_name)
        lines.append(e.sourceline)
    closures = add_constraint_closures(robot, constraints, names, source, lines)
    act = _actuated_joints(root, joints, source) if actuated is None else list(actuated)
    if not closures and not act:      # joints tied by couplings only: the followers follow the rest
        followers = {r.successor_joint for r in relations}
        act = [model.names[j] for j in range(1, model.njoints) if model.joints[j].nv == 1
               and model.names[j] not in followers]
    if closures or relations:
        robot.loops = loop_set(robot, closures, act, relations, source)
    return robot
