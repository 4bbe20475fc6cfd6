"""The rod-end-floating hexapod: geometry, compensated IK and Newton FK, URDF with screw transmissions, calibration
(docs/floating_nut_hexapod.md)."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "calibration": "floating_nut_parameters uncompensated_robot", "kinematics": "FloatingNutKinematics",
    "geometry": "reference_fixture", "urdf": "write_urdf"})
