"""Loop closures as Pinocchio 4.1 constraint models, both ways (docs/closed_loops.md).

Pinocchio describes a closed chain as a kinematic tree plus constraint models; robocal's LoopSet describes it as
the same tree plus closures anchored on two frames each (`<closure>.link1`, `<closure>.link2`, whose placements
are calibration parameters). The kinds map one to one where this wheel has them:

    point closure (3 rows)   PointAnchorConstraintModel   (or RigidConstraintModel CONTACT_3D)
    frame closure (6 rows)   FrameAnchorConstraintModel   (or RigidConstraintModel CONTACT_6D)
    distance, revolute       none in pin 4.1: robocal's own rows (robocal.model.loop_rows)

`pinocchio_constraints` builds Pinocchio's models from a LoopSet's anchor frames (of any calibrated copy of the
model); `add_constraint_closures` turns a user's constraint models (built in Python, or read from MJCF) into
anchor frames and closures (robocal.model.pinocchio_robot: a Pinocchio model and its constraint models in, a
robocal Robot out).

A point closure does not constrain orientation, so its anchor frames keep only their position on the joint:
robocal aligns them with the joint frame (a URDF link frame), whatever rotation the constraint model carried
(MJCF's `connect` derives one from the initial configuration). `<closure>.link2.tx/ty/tz` are then coordinates
in the link's frame, the same for a URDF and an MJCF description of one machine.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.model.loop_rows import ROWS, Closure

#: Pinocchio's constraint classes robocal reads, by kind
KIND_OF = {"PointAnchorConstraintModel": "point", "FrameAnchorConstraintModel": "frame"}
RIGID_KINDS = {"CONTACT_3D": "point", "CONTACT_6D": "frame"}
#: robocal's closure kinds that Pinocchio 4.1 has a constraint model for
PINOCCHIO_KINDS = ("point", "frame")


def pinocchio_constraints(model: pin.Model, closures: list[Closure]) -> pin.StdVec_ConstraintModel:
    """Pinocchio's constraint models of the point and frame closures (in their order), anchored as the closures'
    frames are in `model` (robot.model or a calibrated copy)."""
    out = pin.StdVec_ConstraintModel()
    for closure in closures:
        if closure.kind not in PINOCCHIO_KINDS:
            continue
        f1, f2 = (model.frames[model.getFrameId(name)] for name in (closure.frame1, closure.frame2))
        cls = pin.PointAnchorConstraintModel if closure.kind == "point" else pin.FrameAnchorConstraintModel
        cm = cls(model, f1.parentJoint, f1.placement, f2.parentJoint, f2.placement)
        cm.name = closure.name
        out.append(cm)
        out[len(out) - 1].name = closure.name      # the generic wrapper keeps a name of its own
    return out


def constraint_anchors(cm, model: pin.Model, label: str, source: str):
    """(kind, joint1, placement1, joint2, placement2) of one Pinocchio constraint model; InputError for a kind robocal
    does not read, a joint the model does not have, or a desired offset it cannot fold into the anchors."""
    if isinstance(cm, pin.ConstraintModel):
        cm = cm.extract()
    cls = type(cm).__name__
    if cls == "RigidConstraintModel":
        kind = RIGID_KINDS.get(str(cm.type).rsplit(".", 1)[-1])
    else:
        kind = KIND_OF.get(cls)
    if kind is None:
        what = f"{cls} of type {cm.type}" if cls == "RigidConstraintModel" else cls
        raise InputError(f"constraint {label} is a {what}; robocal reads point and frame anchors "
                         "(PointAnchorConstraintModel, FrameAnchorConstraintModel, RigidConstraintModel CONTACT_3D / "
                         "CONTACT_6D)", source=source, field=label)
    for side in (1, 2):
        jid = int(getattr(cm, f"joint{side}_id"))
        if not 0 <= jid < model.njoints:
            raise InputError(f"constraint {label}: joint{side}_id = {jid} is not a joint of the model (it has "
                             f"joints 0..{model.njoints - 1}; was the constraint built on another model?)",
                             source=source, field=f"{label}.joint{side}_id")
    M1, M2 = cm.joint1_placement.copy(), cm.joint2_placement.copy()
    offset = np.asarray(getattr(cm, "desired_constraint_offset", np.zeros(0)), dtype=float).reshape(-1)
    if offset.size and np.any(offset != 0.0):
        if kind != "point":
            raise InputError(f"constraint {label} has a desired_constraint_offset; robocal reads frame anchors "
                             "without one (fold it into joint1_placement)", source=source, field=label)
        M1 = M1 * pin.SE3(np.eye(3), offset)     # c = R1^T (p2 - p1) - offset: the same zero set
    return kind, int(cm.joint1_id), M1, int(cm.joint2_id), M2


def joint_anchor_parent(robot, jid: int) -> str:
    """A frame carried by joint `jid` to hang anchors on: its link (BODY frame, as a URDF closure names a link),
    else its JOINT frame, else any frame on it; a model built in Python may have none: a joint frame is added."""
    model = robot.model
    on_joint = [k for k, f in enumerate(model.frames) if f.parentJoint == jid]
    rank = {pin.FrameType.BODY: 0, pin.FrameType.JOINT: 1}
    for k in sorted(on_joint, key=lambda k: rank.get(model.frames[k].type, 2)):
        name = model.frames[k].name
        if robot.frame_id(name) == k:      # reachable by its name (names can repeat across frame types)
            return name
    k = model.addJointFrame(jid, -1)
    robot.__dict__.pop("_frame_ids", None)
    return model.frames[k].name


def add_constraint_closures(robot, constraint_models, names=None, source: str = "constraint models",
                            lines=None) -> list[Closure]:
    """Closures of Pinocchio constraint models, with their anchor frames `<name>.link1/.link2` added to
    robot.model. names: one per constraint (default its own `.name`, else "constraint<k>"); lines: the file line of
    each, for error messages."""
    closures, seen = [], set()
    for k, cm in enumerate(constraint_models):
        own = getattr(cm, "name", "") or (cm.extract().name if isinstance(cm, pin.ConstraintModel) else "")
        name = (names[k] if names is not None else None) or own or f"constraint{k + 1}"
        label = f"'{name}' (#{k + 1})"
        row = lines[k] if lines is not None else None
        if name in seen:
            raise InputError(f"two constraints are named '{name}'", source=source, row=row, field=name)
        seen.add(name)
        try:
            kind, j1, M1, j2, M2 = constraint_anchors(cm, robot.model, label, source)
        except InputError as exc:
            raise InputError(exc.reason, source=source, row=row, field=exc.field) from None
        if kind == "point":   # a point closure constrains no orientation: anchors aligned with their joints
            M1, M2 = pin.SE3(np.eye(3), M1.translation), pin.SE3(np.eye(3), M2.translation)
        frames = []
        for side, jid, M in ((1, j1, M1), (2, j2, M2)):
            frames.append(f"{name}.link{side}")
            if robot.model.existFrame(frames[-1]):    # a model that already has them (robot.constraint_models())
                f = robot.model.frames[robot.frame_id(frames[-1])]
                if f.parentJoint != jid or not f.placement.isApprox(M, 1e-12):
                    raise InputError(f"constraint {label}: the model already has a frame '{frames[-1]}' elsewhere",
                                     source=source, row=row, field=frames[-1])
                continue
            parent = joint_anchor_parent(robot, jid)
            relative = robot.model.frames[robot.frame_id(parent)].placement.actInv(M)
            robot.add_frame(frames[-1], parent=parent, placement=relative)
        closures.append(Closure(name, kind, frames[0], frames[1], ROWS[kind]))
    return closures
