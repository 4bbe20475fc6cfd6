"""Stewart (6-UPS) platforms: geometry, closed-form IK and Newton FK, URDF, the five measuring modes and their
calibration (docs/stewart_calibration.md)."""
from robocal.systems.stewart.mode_study import (BALLS, BAR_BASES, HOLES, PLANES, PLATFORM_JOINTS, ModeStudy, fit_machines,
                                                mix)
from robocal.systems.stewart.newton_study import newton_draws

__all__ = ["BALLS", "BAR_BASES", "HOLES", "PLANES", "PLATFORM_JOINTS", "ModeStudy", "fit_machines", "mix", "newton_draws"]
