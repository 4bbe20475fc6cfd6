"""Strut lengths by inverse kinematics: the platform is put where it was measured, no loop is closed.

For each strut j of a sample, three frames of an OPEN (tree) model whose platform is placed at the
measured pose by the sample's readings: the base joint b_j, the platform joint (loop anchor) a_j and
the end of the strut's rod r_j (the rod's own anchor, at the read strut coordinate plus offset):

    r_j = |x(a_j) - x(b_j)| - |x(r_j) - x(b_j)|

i.e. the closed-form IK joint-to-joint length minus o_j + s_j (docs/stewart_calibration.md; e = f(p, x) - s).
It needs no forward kinematics, so it stays defined for parameters far from the truth (the first
stage of a two-stage solve). One term = one sample, one row per strut. No measurement columns: the
measured pose and the strut readings are the sample's joint readings.
"""
from __future__ import annotations

import numpy as np

from robocal.residuals.base import Residual, Term


class StrutIKResidual(Residual):
    """Strut lengths by inverse kinematics: the platform is put where it was measured, no loop is closed. The
    error model, parameters and columns: this module's docstring."""

    type_name = "strut_ik"
    observed = False

    def __init__(self, name, samples, struts, sigma=1e-5, weights=None):
        """struts: [(base frame, platform-anchor frame, rod-end frame)] per strut."""
        self.struts = [tuple(s) for s in struts]
        super().__init__(name, samples, sigma, weights)

    @property
    def dim(self) -> int:
        return len(self.struts)

    @property
    def row_units(self):
        return ("length",) * len(self.struts)

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        s = states[i]
        r = np.zeros(self.dim)
        frames = []
        for j, (fb, fa, fr) in enumerate(self.struts):
            Mb, Ma, Mr = s.pose(fb), s.pose(fa), s.pose(fr)
            da, dr = Ma.translation - Mb.translation, Mr.translation - Mb.translation
            la, lr = np.linalg.norm(da), np.linalg.norm(dr)
            ua, ur = da / la, dr / lr
            r[j] = la - lr
            for frame, u, M in ((fa, ua, Ma), (fb, ur - ua, Mb), (fr, -ur, Mr)):
                D = np.zeros((self.dim, 6))
                D[j, :3] = u @ M.rotation          # d x(M) = R v for M <- M exp6([v; w])
                frames.append((i, frame, D))
        return Term(r, frames)
