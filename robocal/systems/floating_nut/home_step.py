"""The first FK step from the home pose p0, to second order: the start every cold FK solve shares.

The command lengths near p0 are l(p0 + d) = l0 + J0 d + 1/2 H0[d, d] + O(|d|^3) (J0, H0: first and second
derivatives of the compensated IK, or of the plain lengths, at p0). Inverting that series to second order,
    d1 = J0^-1 e,   d = d1 - 1/2 J0^-1 H0[d1, d1],   e = L - l0,
leaves a residual of third order: over 200 poses of the benchmark box (+-0.1 m, +-10 deg) a median of 7e-4 m
after the step instead of 9e-3 m after J0^-1 e, and 3.2 Newton iterations instead of 4 (docs/speed.md). H0 is the central
difference of the analytic Jacobians at p0 +- h e_k, computed once per geometry; a start only has to be close,
the Newton iterations that follow make the pose exact. See docs/floating_nut_hexapod.md and docs/speed.md.
"""
from __future__ import annotations

import numpy as np

#: step of the central differences of the analytic Jacobian that give H0 (error ~h^2, round-off ~1e-16 / h)
HESSIAN_STEP = 1e-5


class HomeStep:
    """Tables of the second-order home step of one FloatingNutKinematics (compensated and plain model)."""

    def __init__(self, kin):
        p0 = kin.geometry.p0
        shifts = p0 + HESSIAN_STEP * np.vstack([np.eye(6), -np.eye(6)])
        self.inverse, self.curvature, self.jacobian = {}, {}, {}
        for compensate in (True, False):
            # J_c(p0), J_l(p0): also the Newton matrices at p0 ("full" and "uncompensated" modes)
            J0 = self.jacobian[compensate] = kin.jacobian(p0, compensate=compensate)
            Js = kin.jacobian(shifts, compensate=compensate)
            H = (Js[:6] - Js[6:]).transpose(1, 2, 0) / (2 * HESSIAN_STEP)     # H[i, j, k] = d2 l_i / dp_j dp_k
            try:
                A = np.linalg.inv(J0)
            except np.linalg.LinAlgError:          # singular at p0: cold solves start at p0 (`ready`)
                self.inverse[compensate] = self.curvature[compensate] = None
                continue
            self.inverse[compensate] = A
            # (36, 6): row 6 i + j holds sum_l A[i, l] H[l, j, :] / 2, so correction_i = sum_j (row . d1) d1_j
            self.curvature[compensate] = np.ascontiguousarray(0.5 * np.einsum("il,ljk->ijk", A, H).reshape(36, 6))

    def ready(self, compensate: bool) -> bool:
        """False when the model's Jacobian at p0 is singular (no home step)."""
        return self.inverse[compensate] is not None

    def step(self, e: np.ndarray, compensate: bool) -> np.ndarray:
        """d (6,) for one residual e = L - l0 (6,)."""
        d1 = self.inverse[compensate].dot(e)
        return d1 - self.curvature[compensate].dot(d1).reshape(6, 6).dot(d1)

    def steps(self, E: np.ndarray, compensate: bool) -> np.ndarray:
        """d (N, 6) for residuals E (N, 6)."""
        D1 = E @ self.inverse[compensate].T
        corr = (D1 @ self.curvature[compensate].T).reshape(-1, 6, 6)
        return D1 - np.einsum("nij,nj->ni", corr, D1)
