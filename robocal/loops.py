"""Loop closures read from URDF.

This module currently only detects closure elements; closed-chain kinematics come with the
parallel-machine support.
"""
from __future__ import annotations

from .errors import InputError


def read_loops(robot, tree):
    """Return the robot's loop closures, or None for a serial (tree) robot."""
    elements = tree.findall("loop_joint") + tree.findall("constraint")
    if not elements:
        return None
    raise InputError("this URDF has loop closures, which robocal cannot read yet",
                     source=str(robot.urdf_path), row=elements[0].sourceline)
