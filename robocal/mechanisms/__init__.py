"""Builders for parallel machines: they write URDF (tree + loop closures) and offer closed-form
kinematics where one exists (see robocal.mechanisms.stewart)."""
from .stewart import StewartGeometry, build_urdf, write_urdf

__all__ = ["StewartGeometry", "build_urdf", "write_urdf"]
