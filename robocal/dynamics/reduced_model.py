"""The model a joint log identifies: the URDF's joints of interest free, every other locked, and log columns
mapped to the model's joint order."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from robocal.errors import InputError


def reduced_model(urdf: Path, joints: list[str]) -> pin.Model:
    """The URDF's model with only `joints` free, the others locked at their neutral value."""
    if not Path(urdf).is_file():
        raise InputError("URDF file not found", source=str(urdf), field="robot.urdf")
    full = pin.buildModelFromUrdf(str(urdf))
    for name in joints:
        if not full.existJointName(name):
            raise InputError(f"joint '{name}' is not in the URDF (it has: "
                             f"{', '.join(full.names[i] for i in range(1, full.njoints))})",
                             source=str(urdf), field="robot.joints")
    lock = [i for i in range(1, full.njoints) if full.names[i] not in joints]
    model = pin.buildReducedModel(full, lock, pin.neutral(full))
    for j in range(1, model.njoints):
        if model.joints[j].nq != 1 or model.joints[j].nv != 1:
            raise InputError(f"joint '{model.names[j]}' is not a one-axis joint (nq {model.joints[j].nq}): "
                             "only revolute and prismatic joints are supported", source=str(urdf),
                             field="robot.joints")
    return model

def velocity_index(model: pin.Model, name: str) -> int:
    return model.joints[model.getJointId(name)].idx_v

def model_columns(model: pin.Model, names: list[str], values: np.ndarray | None) -> np.ndarray | None:
    """Log columns in `names` order -> (T, nv) in the model's joint order (None stays None: a log without them)."""
    if values is None:
        return None
    out = np.zeros((len(values), model.nv))
    for k, name in enumerate(names):
        out[:, velocity_index(model, name)] = values[:, k]
    return out
