"""Double ball bar: distance from a ball on the tool to a ball fixed in the cell.

The bar reads L relative to an unknown zero: r = |M p - c| - (L + offset). Auxiliary: the fixed
ball's centre `<name>.centre.{x,y,z}`, the zero offset `<name>.offset` (both usually unknown), the
tool ball `<name>.tip.{x,y,z}` in the frame. Measurement column: the length reading.
"""
from __future__ import annotations

import numpy as np

from robocal.residuals.base import Aux, Residual, Term, distance_terms, point_jacobian, vector_aux


class BallBarResidual(Residual):
    """Double ball bar: distance from a ball on the tool to a ball fixed in the cell. The error model,
    parameters and columns: this module's docstring."""

    type_name = "ball_bar"

    def __init__(self, name, frame, samples, measurements, centre, offset=0.0, centre_unknown=True,
                 offset_unknown=True, point=(0.0, 0.0, 0.0), point_unknown=False, sigma=1e-5, weights=None,
                 columns=None):
        super().__init__(name, samples, sigma, weights)
        self.frame = frame
        self.aux = (vector_aux("centre", centre, "m", centre_unknown) + [Aux("offset", float(offset), "m", offset_unknown)]
                    + vector_aux("tip", point, "m", point_unknown))
        self.columns = list(columns or [f"{name}.length"])
        self.measurements = np.asarray(measurements, dtype=float).reshape(-1, 1)

    dim = 1
    row_units = ("length",)

    def _distance(self, M, aux):
        w = M.act(aux[4:7]) - aux[:3]
        return np.linalg.norm(w), w

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        M = states[i].pose(self.frame)
        dist, w = self._distance(M, aux)
        e = w / dist
        r = np.array([dist - self.measurements[k, 0] - aux[3]])
        A = np.concatenate([-e, [-1.0], e @ M.rotation])[None, :]
        return Term(r, [(i, self.frame, (e @ point_jacobian(M, aux[4:7]))[None, :])], A)

    def evaluate_batch(self, terms, R, p, aux):
        return distance_terms(R, p, aux, self.measurements[terms, 0])

    def simulate(self, k, states, aux, rng):
        dist, _ = self._distance(states[self.samples[k]].pose(self.frame), aux)
        return np.array([dist - aux[3] + rng.normal(0.0, self.sigma[0])])
