"""Stewart (6-UPS) platforms: geometry, closed-form IK and Newton FK, URDF, the five measuring modes and their
calibration (docs/stewart_calibration.md)."""
from robocal.systems.stewart.mode_study import BALLS, BAR_BASES, HOLES, PLANES, ModeStudy, fit_machines, mix

__all__ = ["BALLS", "BAR_BASES", "HOLES", "PLANES", "ModeStudy", "fit_machines", "mix"]
