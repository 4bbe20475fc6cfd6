"""Direction of a frame's axis (a tool's axis measured by a tilt sensor or a jig): tilt without spin.

Used where the rotation about the tool axis is not measured (the Stewart spec's u_C = 0 rows): unlike a
pose residual with its C row dropped, this residual is blind to the spin about the axis on tilted poses.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.model.lie_arrays import skew
from robocal.residuals.base import Residual, Term, basis_from_normal


class ToolAxisResidual(Residual):
    """Tilt of a frame's axis e (default z): r = B^T R e (2 rows, rad for small errors).

    B (3, 2) spans the plane normal to the measured axis a_meas, so the rows are the two tilt angles of
    R e away from a_meas; a third row along a_meas would be second order and carry no information, and
    would count one degree of freedom too many per sample in sigma-hat and chi^2.
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
        self.bases = np.array([basis_from_normal(a)[:, :2] for a in self.measurements]).reshape(-1, 3, 2)

    dim = 2
    row_units = ("angle",) * 2

    @classmethod
    def column_kinds(cls, n_columns):
        return [""] * n_columns

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        R = states[i].pose(self.frame).rotation
        B = self.bases[k]
        D = np.zeros((2, 6))
        D[:, 3:] = -B.T @ R @ skew(self.axis)    # d(R e) = R (w x e) for M <- M exp6([v; w])
        return Term(B.T @ R @ self.axis, [(i, self.frame, D)])

    def simulate(self, k, states, aux, rng):
        a = states[self.samples[k]].pose(self.frame).rotation @ self.axis
        # a small rotation about a direction normal to the axis: each of the two tilt rows gets its sigma
        return pin.exp3(basis_from_normal(a)[:, :2] @ rng.normal(0.0, self.sigma)) @ a
