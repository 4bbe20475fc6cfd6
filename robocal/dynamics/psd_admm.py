"""Convex least squares with every body's pseudo-inertia positive semidefinite, by ADMM.

    minimise 1/2 x^T H x - q^T x   over x = [pi (10 nb), phi (n_extra)]
    subject to  pseudo_inertia(pi_b) PSD for every body b,  phi >= lower

The pseudo-inertia is linear in pi (inertial.py), so this is a convex problem whose constraint set
is a product of 4x4 PSD cones and a box. ADMM (Boyd et al. 2011, scaled form) splits z = M x with M
mapping each body's pi to its pseudo-inertia in the isometric `svec` coordinates (off-diagonal
entries x sqrt 2), where the Euclidean projection onto the cone is the eigenvalue clip. The
returned parameters are the projected z mapped back: every body passes the PSD test exactly (up to
rounding), whatever the iteration count. rho is adapted by residual balancing.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from robocal.dynamics.inertial import params_from_pseudo_inertia, pseudo_inertia

_ROWS, _COLS = np.triu_indices(4)
_WEIGHT = np.where(_ROWS == _COLS, 1.0, np.sqrt(2.0))


def svec(J: np.ndarray) -> np.ndarray:
    """10 isometric coordinates of a symmetric 4x4 (Frobenius norm = Euclidean norm)."""
    return J[..., _ROWS, _COLS] * _WEIGHT


def smat(s: np.ndarray) -> np.ndarray:
    out = np.zeros(s.shape[:-1] + (4, 4))
    out[..., _ROWS, _COLS] = s / _WEIGHT
    out[..., _COLS, _ROWS] = s / _WEIGHT
    return out


#: pi (10) -> svec(pseudo-inertia) (10), linear and invertible
TO_SVEC = np.column_stack([svec(pseudo_inertia(e)) for e in np.eye(10)])
FROM_SVEC = np.column_stack([params_from_pseudo_inertia(smat(e)) for e in np.eye(10)])


@dataclass
class AdmmResult:
    x: np.ndarray
    iterations: int
    primal_residual: float
    dual_residual: float
    converged: bool
    state: tuple


def solve_psd_qp(H: np.ndarray, q: np.ndarray, n_bodies: int, lower: np.ndarray, warm: tuple | None = None,
                 start: np.ndarray | None = None, tol: float = 1e-5, max_iterations: int = 20000) -> AdmmResult:
    """Minimise 1/2 x^T H x - q^T x with the constraints of the module docstring.
    lower: (n_extra,) bounds on phi (-inf where free); warm: `state` of a previous result (same
    problem size; its scaling is kept);
    start: a first guess of x when there is no warm state (e.g. the CAD values)."""
    n_in = 10 * n_bodies
    n = H.shape[0]
    if warm is None:
        scale = _scaling(H, n_bodies)
    else:
        scale = warm[3]
    M = np.diag(scale)
    for b in range(n_bodies):
        M[10 * b:10 * b + 10, 10 * b:10 * b + 10] = scale[10 * b] * TO_SVEC
    MtM = M.T @ M
    low = lower * scale[n_in:]                # the box in z coordinates (positive scaling)
    if warm is None:
        z0 = _project(M @ (np.zeros(n) if start is None else start), n_bodies, low)
        warm = (z0, np.zeros(n), 1.0, scale)
    z, u, rho, _ = warm
    factor = scipy.linalg.cho_factor(H + rho * MtM)
    scale_p = scale_d = 1.0
    for it in range(1, max_iterations + 1):
        x = scipy.linalg.cho_solve(factor, q + rho * M.T @ (z - u))
        Mx = M @ x
        z_old = z
        z = _project(Mx + u, n_bodies, low)
        u = u + Mx - z
        r = np.linalg.norm(Mx - z)
        s = rho * np.linalg.norm(M.T @ (z - z_old))
        scale_p = max(np.linalg.norm(Mx), np.linalg.norm(z), 1e-12)
        scale_d = max(np.linalg.norm(rho * M.T @ u), 1e-12)
        if r <= tol * scale_p and s <= tol * scale_d:
            break
        if it % 10 == 0 and (r / scale_p > 10 * s / scale_d or s / scale_d > 10 * r / scale_p):
            ratio = 2.0 if r / scale_p > s / scale_d else 0.5       # residual balancing
            rho *= ratio
            u /= ratio
            factor = scipy.linalg.cho_factor(H + rho * MtM)
    x_out = z / scale                       # the projected point: feasible by construction
    for b in range(n_bodies):
        x_out[10 * b:10 * b + 10] = FROM_SVEC @ z[10 * b:10 * b + 10] / scale[10 * b]
    return AdmmResult(x_out, it, float(r / scale_p), float(s / scale_d),
                      bool(r <= tol * scale_p and s <= tol * scale_d), (z, u, rho, scale))


def _scaling(H: np.ndarray, n_bodies: int) -> np.ndarray:
    """Diagonal preconditioning compatible with the cones: one positive factor per body (the PSD cone
    is invariant under it) and one per extra term (the box too), so that M^T M matches H's diagonal."""
    d = np.sqrt(np.maximum(np.diag(H), 0.0))
    d[d == 0] = 1.0
    norm = np.linalg.norm(TO_SVEC, axis=0)
    for b in range(n_bodies):
        sl = slice(10 * b, 10 * b + 10)
        d[sl] = np.exp(np.mean(np.log(d[sl] / norm)))
    return d


def _project(v: np.ndarray, n_bodies: int, lower: np.ndarray) -> np.ndarray:
    n_in = 10 * n_bodies
    out = v.copy()
    J = smat(v[:n_in].reshape(n_bodies, 10))
    eig, vec = np.linalg.eigh(J)
    out[:n_in] = svec((vec * np.maximum(eig, 0.0)[:, None, :]) @ vec.transpose(0, 2, 1)).reshape(-1)
    out[n_in:] = np.maximum(v[n_in:], lower)
    return out
