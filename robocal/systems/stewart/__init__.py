"""Stewart (6-UPS) platforms: geometry, closed-form IK and Newton FK, URDF, the five measuring modes and their
calibration (docs/stewart_calibration.md)."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "mode_study": "BALLS BAR_BASES HOLES fit_machines mix ModeStudy PLANES"})
