"""OpenCV, where the optional extra is installed (`pip install robocal[camera]`: opencv-python-headless).

Everything camera-related works without it (robocal's own PnP and closed-form hand-eye); with it, robocal uses
OpenCV's solvePnP, calibrateHandEye, calibrateCamera and its target detectors. The API is checked, not the version
number: OpenCV 5.0's Python wheel has no calibrateHandEye (measured on 5.0.0.93), aruco moved into the main module
in 4.7 (ArucoDetector, CharucoDetector).
"""
from __future__ import annotations

from functools import lru_cache


@lru_cache(maxsize=1)
def opencv():
    """The cv2 module, or None when the extra is not installed."""
    try:
        import cv2     # optional extra (camera): imported only when a camera feature asks for it
    except ImportError:
        return None
    return cv2


def has(*names: str) -> bool:
    """Whether OpenCV is installed and has every dotted name (`calibrateHandEye`, `aruco.CharucoDetector`)."""
    cv2 = opencv()
    if cv2 is None:
        return False
    for name in names:
        obj = cv2
        for part in name.split("."):
            obj = getattr(obj, part, None)
            if obj is None:
                return False
    return True


def require(*names: str, what: str = "this"):
    """cv2, or an ImportError that says what to install (and which functions the installed OpenCV lacks)."""
    cv2 = opencv()
    if cv2 is None:
        raise ImportError(f"{what} needs OpenCV: pip install 'robocal[camera]' (opencv-python-headless)")
    missing = [n for n in names if not has(n)]
    if missing:
        raise ImportError(f"{what} needs cv2.{missing[0]}, which OpenCV {cv2.__version__} does not have; "
                          "pip install 'opencv-python-headless>=4.8,<5'")
    return cv2
