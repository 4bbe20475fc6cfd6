"""Several points of one rigid body in one sample (a mocap cluster, a tracker's multi-reflector tool).

r = [M p_1 - y_1; ...; M p_k - y_k]. The points' coordinates in the body frame are auxiliary
parameters `<name>.<label>.{x,y,z}`, known or estimated. With the frame's placement free as well,
one rigid motion of all points is confounded with it; the identifiability report says so.
Measurement columns: x y z of each point, in label order.
"""
from __future__ import annotations

import numpy as np

from robocal.residuals.base import Residual, Term, point_jacobian, vector_aux


class RigidPointsResidual(Residual):
    """Several points of one rigid body in one sample (a mocap cluster, a tracker's multi-reflector tool). The
    error model, parameters and columns: this module's docstring."""

    type_name = "rigid_points"

    def __init__(self, name, frame, samples, measurements, points, labels=None, points_unknown=False,
                 sigma=1e-4, weights=None, columns=None):
        self.points0 = np.asarray(points, dtype=float).reshape(-1, 3)
        self.labels = list(labels or [f"p{i + 1}" for i in range(len(self.points0))])
        super().__init__(name, samples, sigma, weights)
        self.frame = frame
        self.aux = [a for lab, p in zip(self.labels, self.points0) for a in vector_aux(lab, p, "m", points_unknown)]
        self.columns = list(columns or [f"{name}.{lab}.{c}" for lab in self.labels for c in "xyz"])
        self.measurements = np.asarray(measurements, dtype=float).reshape(-1, self.dim)

    @property
    def dim(self):
        return 3 * len(self.points0)

    @property
    def row_units(self):
        return ("length",) * self.dim

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        M = states[i].pose(self.frame)
        P = aux.reshape(-1, 3)
        r = (P @ M.rotation.T + M.translation).reshape(-1) - self.measurements[k]
        D = np.vstack([point_jacobian(M, p) for p in P])
        A = np.zeros((self.dim, self.dim))
        for j in range(len(P)):
            A[3 * j:3 * j + 3, 3 * j:3 * j + 3] = M.rotation
        return Term(r, [(i, self.frame, D)], A)

    def simulate(self, k, states, aux, rng):
        M = states[self.samples[k]].pose(self.frame)
        P = aux.reshape(-1, 3)
        return (P @ M.rotation.T + M.translation).reshape(-1) + rng.normal(0.0, self.sigma)
