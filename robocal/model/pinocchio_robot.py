"""A robocal Robot from a Pinocchio model and its constraint models: the Python entry point for a closed chain a
Pinocchio user already has (built in Python, or read by Pinocchio from MJCF). docs/closed_loops.md."""
from __future__ import annotations

import pinocchio as pin

from robocal.errors import InputError
from robocal.model.constraint_models import add_constraint_closures
from robocal.model.loops import loop_set
from robocal.model.robot import Robot


def robot_from_pinocchio(model: pin.Model, constraint_models=(), actuated=(), name: str = "", relations=None,
                         source: str = "constraint models") -> Robot:
    """A robocal Robot from a Pinocchio model (the spanning tree) and its constraint models (the loops).

    constraint_models  PointAnchor / FrameAnchor constraint models (concrete, generic ConstraintModel, or legacy
                       RigidConstraintModel CONTACT_3D / 6D), e.g. from pin.buildModelAndConstraintsFromMJCF or built
                       in Python; their `.name` names the closures (default constraint1, constraint2, ...)
    actuated           the 1-dof joints read by encoders, in the readings' order (required with closures)
    relations          joint relations (robocal.model.joint_relations.Coupling, ScrewTransmission), optional
    source             what error messages call the input
    The model is copied (the anchor frames `<name>.link1/.link2` are added to the copy).
    """
    robot = Robot(model=model.copy(), name=name or model.name or "robot")
    closures = add_constraint_closures(robot, list(constraint_models), source=source)
    if closures or relations:
        robot.loops = loop_set(robot, closures, list(actuated), list(relations or []), source)
    elif actuated:
        raise InputError("actuated joints were named but there are no constraint models: a tree robot reads "
                         "every joint", source=source, field="actuated")
    return robot
