"""3D position of a point on a link (tracker reflector, mocap marker, probe centre).

r = M p - y in the measurement frame. The point p in the frame is an auxiliary parameter group
`<name>.point.{x,y,z}`: known (fixed) or unknown (estimated).
Measurement columns: x y z.
"""
from __future__ import annotations

import numpy as np

from robocal.model import lie_arrays
from robocal.residuals.base import BatchTerms, Residual, Term, point_jacobian, vector_aux


class PointResidual(Residual):
    """3D position of a point on a link (tracker reflector, mocap marker, probe centre). The error model,
    parameters and columns: this module's docstring."""

    type_name = "point"

    def __init__(self, name, frame, samples, measurements, point=(0.0, 0.0, 0.0), point_unknown=False,
                 sigma=1e-4, weights=None, columns=None):
        super().__init__(name, samples, sigma, weights)
        self.frame = frame
        self.aux = vector_aux("point", point, "m", point_unknown)
        self.columns = list(columns or [f"{name}.{c}" for c in "xyz"])
        self.measurements = np.asarray(measurements, dtype=float).reshape(-1, 3)

    dim = 3
    row_units = ("length",) * 3

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        M = states[i].pose(self.frame)
        r = M.act(aux[:3]) - self.measurements[k]
        return Term(r, [(i, self.frame, point_jacobian(M, aux[:3]))], M.rotation.copy())

    def evaluate_batch(self, terms, R, p, aux):
        r = lie_arrays.act(R, p, aux[:3]) - self.measurements[terms]
        return BatchTerms(r, lie_arrays.point_jacobian(R, aux[:3]), R.copy())

    def simulate(self, k, states, aux, rng):
        return states[self.samples[k]].pose(self.frame).act(aux[:3]) + rng.normal(0.0, self.sigma)
