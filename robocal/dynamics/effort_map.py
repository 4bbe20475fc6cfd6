"""Logged efforts to joint torques: torque_j = effort_j x scale_j + offset_j, per recorded joint (scale: gear
ratio x motor constant; offset: a constant, e.g. a carried weight the drive's reading leaves out).

The one place where a log's effort signals become the torques the model predicts: the identification and
the prediction on a new log (identify_evaluate.py) both go through it, and the identified model's side file
stores it. Its `recorded` are the fit's channels: recorded joints, or with a transmission the logged motors
(scale: their torque constants, or 1 for motor torques). A coupled transmission does not turn the efforts into
joint torques here: the rows stay the motors' (channels.py, where their noise is their own) and the matrix
enters the regressor (docs/dynamics_motors.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class EffortMap:
    """recorded: the joints whose effort is logged (model order); scale, offset (nr,)."""

    recorded: list[str]
    scale: np.ndarray
    offset: np.ndarray

    def torques(self, effort: np.ndarray) -> np.ndarray:
        """(T, nr) joint torques from the recorded joints' effort columns (T, nr), in `recorded` order."""
        return np.asarray(effort, float) * self.scale + self.offset

    def to_dict(self) -> dict:
        return {"recorded": list(self.recorded),
                "scale": {j: float(s) for j, s in zip(self.recorded, self.scale)},
                "offset": {j: float(o) for j, o in zip(self.recorded, self.offset)}}

    @classmethod
    def from_dict(cls, d: dict) -> "EffortMap":
        rec = list(d["recorded"])
        return cls(rec, np.array([float(d["scale"][j]) for j in rec]),
                   np.array([float(d.get("offset", {}).get(j, 0.0)) for j in rec]))
