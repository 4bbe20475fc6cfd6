"""The rod-end-floating hexapod: geometry, compensated IK and Newton FK, URDF with screw transmissions, calibration
(docs/floating_nut_hexapod.md)."""
from robocal.systems.floating_nut.calibration import floating_nut_parameters, uncompensated_robot
from robocal.systems.floating_nut.geometry import reference_fixture
from robocal.systems.floating_nut.kinematics import FloatingNutKinematics
from robocal.systems.floating_nut.urdf import write_urdf

__all__ = ["floating_nut_parameters", "uncompensated_robot", "reference_fixture", "FloatingNutKinematics",
           "write_urdf"]
