"""A probe tip touching a plane (reference surface, jig face).

The tip is a ball of radius `tip_radius` centred at point p of a frame; at contact its centre lies
`tip_radius` above the plane on the side the normal points to: r = n . (M p) - d - tip_radius.
The plane is n(tilt) . x = d with n = R0 [a, b, 1]/|.| about its initial normal n0 (two tilts and an
offset, the minimal parametrisation), auxiliary `<name>.tilt_a`, `.tilt_b`, `.offset`: known or estimated.
No measurement columns: the joint readings at contact are the data.
"""
from __future__ import annotations

import numpy as np

from robocal.model import lie_arrays
from robocal.residuals.base import (Aux, BatchTerms, Residual, Term, basis_from_normal, point_jacobian,
                                     tilted_direction, vector_aux)


class PlaneResidual(Residual):
    """A probe tip touching a plane (reference surface, jig face). The error model, parameters and columns: this
    module's docstring."""

    type_name = "plane"
    observed = False

    def __init__(self, name, frame, samples, normal, offset, plane_unknown=True, point=(0.0, 0.0, 0.0),
                 point_unknown=False, tip_radius=0.0, sigma=1e-5, weights=None):
        super().__init__(name, samples, sigma, weights)
        self.frame = frame
        self.R0 = basis_from_normal(normal)
        self.aux = [Aux("tilt_a", 0.0, "rad", plane_unknown), Aux("tilt_b", 0.0, "rad", plane_unknown),
                    Aux("offset", float(offset), "m", plane_unknown)] + vector_aux("tip", point, "m", point_unknown)
        self.tip_radius = float(tip_radius)

    dim = 1
    row_units = ("length",)

    def normal(self, aux):
        return tilted_direction(self.R0, aux[0], aux[1])[0]

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        M = states[i].pose(self.frame)
        p = aux[3:6]
        x = M.act(p)
        n, dn = tilted_direction(self.R0, aux[0], aux[1])
        r = np.array([n @ x - aux[2] - self.tip_radius])
        A = np.concatenate([x @ dn, [-1.0], n @ M.rotation])[None, :]
        return Term(r, [(i, self.frame, (n @ point_jacobian(M, p))[None, :])], A)

    def evaluate_batch(self, terms, R, p, aux):
        tip = aux[3:6]
        x = lie_arrays.act(R, p, tip)
        n, dn = tilted_direction(self.R0, aux[0], aux[1])
        r = (x @ n - aux[2] - self.tip_radius)[:, None]
        A = np.concatenate([x @ dn, -np.ones((len(x), 1)), np.einsum("i,nij->nj", n, R)], axis=1)[:, None, :]
        D = np.einsum("i,nij->nj", n, lie_arrays.point_jacobian(R, tip))[:, None, :]
        return BatchTerms(r, D, A)
