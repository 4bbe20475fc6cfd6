"""Direction of a frame's axis (a tool's axis measured by a tilt sensor or a jig): tilt without spin.

Used where the rotation about the tool axis is not measured (the Stewart spec's u_C = 0 rows): unlike a
pose residual with its C row dropped, this residual is blind to the spin about the axis on tilted poses.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from .base import Residual, Term, skew


class ToolAxisResidual(Residual):
    """Tilt of a frame's axis e (default z): r = R e - a_meas (3 rows, rad for small errors).

    The spin about e does not change r, so it measures A and B but not C under any convention.
    Measurement columns: the measured unit axis a_meas (x y z) in the measurement frame.
    """

    type_name = "tool_axis"

    def __init__(self, name, frame, samples, measurements, axis=(0.0, 0.0, 1.0), sigma=1e-4, weights=None,
                 columns=None):
        super().__init__(name, samples, sigma, weights)
        self.frame = frame
        self.axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        self.columns = list(columns or [f"{name}.{c}" for c in "xyz"])
        m = np.asarray(measurements, dtype=float).reshape(-1, 3)
        self.measurements = m / np.linalg.norm(m, axis=1, keepdims=True)

    dim = 3
    row_units = ("angle",) * 3

    @classmethod
    def column_kinds(cls, n_columns):
        return [""] * n_columns

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        R = states[i].pose(self.frame).rotation
        D = np.zeros((3, 6))
        D[:, 3:] = -R @ skew(self.axis)          # d(R e) = R (w x e) for M <- M exp6([v; w])
        return Term(R @ self.axis - self.measurements[k], [(i, self.frame, D)])

    def simulate(self, k, states, aux, rng):
        R = states[self.samples[k]].pose(self.frame).rotation
        return pin.exp3(rng.normal(0.0, self.sigma)) @ R @ self.axis
