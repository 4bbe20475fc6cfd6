"""A laser beam on a frame passing through a fixed, unknown point (laser + position-sensitive detector).

The beam leaves origin o along u = R0 [a, b, 1]/|.| (both in the frame); the fixed point P is in the
measurement frame. With v = M^-1 P - o and v_perp = v - (u.v) u, the two rows are the components of
v_perp along R0's x and y axes: zero exactly when the beam passes through P. Auxiliary: `<name>.target.{x,y,z}`
(P), `<name>.origin.{x,y,z}`, `<name>.tilt_a`, `.tilt_b` (beam direction). No measurement columns.
"""
from __future__ import annotations

import numpy as np

from .base import Aux, Residual, Term, basis_from_normal, skew, tilted_direction, vector_aux


class LaserLineResidual(Residual):
    type_name = "laser_line"
    observed = False

    def __init__(self, name, frame, samples, target, origin=(0.0, 0.0, 0.0), direction=(0.0, 0.0, 1.0),
                 target_unknown=True, beam_unknown=False, sigma=1e-5, weights=None):
        super().__init__(name, samples, sigma, weights)
        self.frame = frame
        self.R0 = basis_from_normal(direction)
        self.aux = (vector_aux("target", target, "m", target_unknown) + vector_aux("origin", origin, "m", beam_unknown)
                    + [Aux("tilt_a", 0.0, "rad", beam_unknown), Aux("tilt_b", 0.0, "rad", beam_unknown)])

    dim = 2
    row_units = ("length", "length")

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        M = states[i].pose(self.frame)
        P, o = aux[:3], aux[3:6]
        u, du = tilted_direction(self.R0, aux[6], aux[7])
        Pf = M.actInv(P)
        v = Pf - o
        Proj = np.eye(3) - np.outer(u, u)
        G = self.R0[:, :2].T @ Proj           # rows of r = G v
        dG_du = -self.R0[:, :2].T @ ((u @ v) * np.eye(3) + np.outer(u, v))   # d(Proj v)/du, projected
        r = G @ v
        D = G @ np.hstack([-np.eye(3), skew(Pf)])
        A = np.hstack([G @ M.rotation.T, -G, dG_du @ du])
        return Term(r, [(i, self.frame, D)], A)
