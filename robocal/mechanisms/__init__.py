"""Builders for parallel machines: they write URDF (tree + loop closures) and offer closed-form
kinematics where one exists."""
