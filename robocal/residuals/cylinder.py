"""A probe tip touching a cylinder: inside a bore (hole) or around a pin.

Distance of the tip centre from the axis: h = |(I - u u^T)(M p - a)|. In a hole the tip touches at
h = radius - tip_radius, on a pin at h = radius + tip_radius; r = h - that. The axis is
a = a0 + R0 [s, t, 0] and u = R0 [a, b, 1]/|.| about its initial point a0 and direction u0, auxiliary
`<name>.shift_s`, `.shift_t`, `.tilt_a`, `.tilt_b`, and `<name>.radius`. No measurement columns.
"""
from __future__ import annotations

import numpy as np

from robocal.residuals.base import Aux, Residual, Term, basis_from_normal, point_jacobian, tilted_direction, vector_aux


class CylinderResidual(Residual):
    """A probe tip touching a cylinder: inside a bore (hole) or around a pin. The error model, parameters and
    columns: this module's docstring."""

    type_name = "cylinder"
    observed = False

    def __init__(self, name, frame, samples, axis_point, axis_direction, radius, inside=True, axis_unknown=True,
                 radius_unknown=False, point=(0.0, 0.0, 0.0), point_unknown=False, tip_radius=0.0, sigma=1e-5,
                 weights=None):
        super().__init__(name, samples, sigma, weights)
        self.frame = frame
        self.a0 = np.asarray(axis_point, dtype=float).reshape(3)
        self.R0 = basis_from_normal(axis_direction)
        self.aux = ([Aux(s, 0.0, "m", axis_unknown) for s in ("shift_s", "shift_t")]
                    + [Aux(s, 0.0, "rad", axis_unknown) for s in ("tilt_a", "tilt_b")]
                    + [Aux("radius", float(radius), "m", radius_unknown)] + vector_aux("tip", point, "m", point_unknown))
        self.contact_sign = -1.0 if inside else 1.0
        self.tip_radius = float(tip_radius)

    dim = 1
    row_units = ("length",)

    def axis(self, aux):
        return self.a0 + self.R0[:, :2] @ aux[:2], tilted_direction(self.R0, aux[2], aux[3])[0]

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        M = states[i].pose(self.frame)
        p = aux[5:8]
        a = self.a0 + self.R0[:, :2] @ aux[:2]
        u, du = tilted_direction(self.R0, aux[2], aux[3])
        w = M.act(p) - a
        perp = w - (w @ u) * u
        h = np.linalg.norm(perp)
        e = perp / h
        r = np.array([h - aux[4] - self.contact_sign * self.tip_radius])
        # dh/dx = e (e is orthogonal to u); dh/du = -(w.u) e
        A = np.concatenate([-e @ self.R0[:, :2], -(w @ u) * (e @ du), [-1.0], e @ M.rotation])[None, :]
        return Term(r, [(i, self.frame, (e @ point_jacobian(M, p))[None, :])], A)
