"""Attach a tool or payload inertia to a frame, on a copy of the model."""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.errors import InputError


def payload_inertia(mass: float, com: np.ndarray, inertia_at_com: np.ndarray | None = None) -> pin.Inertia:
    """A rigid payload: mass kg, com (3,) m in the frame it is attached to, rotational inertia
    (3, 3) kg m^2 about the com (a point mass when None)."""
    if not mass >= 0:
        raise InputError(f"payload mass must be >= 0 kg, got {mass}", field="mass")
    inertia = np.zeros((3, 3)) if inertia_at_com is None else np.asarray(inertia_at_com, dtype=float)
    return pin.Inertia(float(mass), np.asarray(com, dtype=float).reshape(3), inertia)


def with_payload(model: pin.Model, frame_id: int, inertia: pin.Inertia) -> pin.Model:
    """A copy of `model` whose body carrying `frame_id` also carries `inertia` (expressed in that
    frame). The nominal model is not touched."""
    out = model.copy()
    frame = out.frames[frame_id]
    joint = frame.parentJoint
    if joint == 0:
        raise InputError("a payload on a frame fixed to the world has no effect", field="frame")
    out.inertias[joint] = out.inertias[joint] + frame.placement.act(inertia)
    return out
