"""Geometric least-squares sphere fit and its analytic sensitivity to the points.

fit_sphere minimises sum_k (|X_k - c| - r)^2 by Gauss-Newton started from the algebraic fit
(|X|^2 = 2 c.X + k, r^2 = k + |c|^2). sphere_fit_sensitivity gives d[c; r]/dX (4, 3N) by the
implicit-function theorem on the optimality condition J^T res = 0, exact also at non-zero residual;
at zero residual it reduces to (G^T G)^-1 G^T diag(n_k^T) with G = [n_k^T 1] (docs/pcmm_calibration.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError

COPLANAR_RTOL = 1e-9


@dataclass
class SphereFit:
    centre: np.ndarray     # (3,)
    radius: float
    rms: float             # RMS of the radial residuals |X_k - c| - r
    residuals: np.ndarray  # (N,)
    iterations: int


def _check(points, source: str) -> np.ndarray:
    X = np.asarray(points, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3:
        raise InputError(f"sphere fit needs an (N, 3) array of points, got shape {X.shape}", source=source,
                         field="points")
    if len(X) < 4:
        raise InputError(f"sphere fit needs at least 4 points, got {len(X)}", source=source, field="points")
    if not np.all(np.isfinite(X)):
        row = int(np.argwhere(~np.isfinite(X))[0, 0])
        raise InputError("sphere fit: point is not finite", source=source, row=row + 1, field="points")
    s = np.linalg.svd(X - X.mean(axis=0), compute_uv=False)
    if s[2] <= COPLANAR_RTOL * s[0]:
        raise InputError(f"sphere fit: the {len(X)} points are coplanar or collinear (singular values "
                         f"{s[0]:.3g}, {s[1]:.3g}, {s[2]:.3g}); a sphere is not determined", source=source,
                         field="points")
    return X


def fit_sphere(points, source: str = "points", tol: float = 1e-13, max_iter: int = 100) -> SphereFit:
    """Geometric least-squares sphere through (N, 3) points, N >= 4, not coplanar (else InputError).

    Gauss-Newton stops when the step is below tol * size of the point set, or stalls at round-off.

    `source` names the points in error messages (e.g. "placement 3, sphere 2").
    """
    X = _check(points, source)
    A = np.column_stack([2.0 * X, np.ones(len(X))])
    sol = np.linalg.lstsq(A, np.einsum("na,na->n", X, X), rcond=None)[0]
    c = sol[:3]
    r = np.sqrt(max(sol[3] + c @ c, 0.0))
    scale = max(r, np.ptp(X, axis=0).max())
    it, last = 0, np.inf
    for it in range(1, max_iter + 1):
        w = X - c
        d = np.linalg.norm(w, axis=1)
        n = w / d[:, None]
        res = d - r
        J = np.column_stack([-n, -np.ones(len(X))])
        step = np.linalg.lstsq(J, -res, rcond=None)[0]
        c, r = c + step[:3], r + step[3]
        size = np.linalg.norm(step)
        # converged, or stalled at round-off (quadratic convergence ended: the step no longer shrinks)
        if size <= tol * scale or (size >= last and size < 1e-9 * scale):
            break
        last = size
    d = np.linalg.norm(X - c, axis=1)
    res = d - r
    return SphereFit(c, float(r), float(np.sqrt(np.mean(res ** 2))), res, it)


def sphere_fit_sensitivity(points, centre, radius) -> np.ndarray:
    """(4, 3N) derivative of the fitted [c; r] with respect to the stacked points [X_1; ...; X_N]."""
    X = np.asarray(points, dtype=float)
    w = X - np.asarray(centre, dtype=float)
    d = np.linalg.norm(w, axis=1)
    n = w / d[:, None]
    res = d - radius
    N = len(X)
    P = (np.eye(3)[None] - n[:, :, None] * n[:, None, :]) / d[:, None, None]    # dn_k/dX_k, (N, 3, 3)
    G = np.column_stack([n, np.ones(N)])                                         # = -J
    H = G.T @ G
    H[:3, :3] += np.einsum("k,kab->ab", res, P)
    # d(J^T res)/dX_k = -G_k^T n_k^T - res_k [P_k; 0]
    dg = -G[:, :, None] * n[:, None, :]                                           # (N, 4, 3)
    dg[:, :3, :] -= res[:, None, None] * P
    S = -np.linalg.solve(H, dg.transpose(1, 0, 2).reshape(4, 3 * N))
    return S
