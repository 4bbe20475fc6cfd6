"""A probe tip touching a sphere (reference ball) from outside.

r = |M p - c| - (radius + tip_radius). Auxiliary: centre `<name>.centre.{x,y,z}` (usually unknown) and
`<name>.radius` (usually known from the ball's certificate). No measurement columns.
"""
from __future__ import annotations

import numpy as np

from robocal.residuals.base import Aux, Residual, Term, distance_terms, point_jacobian, vector_aux


class SphereResidual(Residual):
    """A probe tip touching a sphere (reference ball) from outside. The error model, parameters and columns:
    this module's docstring."""

    type_name = "sphere"
    observed = False

    def __init__(self, name, frame, samples, centre, radius, centre_unknown=True, radius_unknown=False,
                 point=(0.0, 0.0, 0.0), point_unknown=False, tip_radius=0.0, sigma=1e-5, weights=None):
        super().__init__(name, samples, sigma, weights)
        self.frame = frame
        self.aux = (vector_aux("centre", centre, "m", centre_unknown) + [Aux("radius", float(radius), "m", radius_unknown)]
                    + vector_aux("tip", point, "m", point_unknown))
        self.tip_radius = float(tip_radius)

    dim = 1
    row_units = ("length",)

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        M = states[i].pose(self.frame)
        c, p = aux[:3], aux[4:7]
        w = M.act(p) - c
        dist = np.linalg.norm(w)
        e = w / dist
        r = np.array([dist - aux[3] - self.tip_radius])
        A = np.concatenate([-e, [-1.0], e @ M.rotation])[None, :]
        return Term(r, [(i, self.frame, (e @ point_jacobian(M, p))[None, :])], A)

    def evaluate_batch(self, terms, R, p, aux):
        return distance_terms(R, p, aux, self.tip_radius)
