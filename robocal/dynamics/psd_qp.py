"""Convex least squares with every body's pseudo-inertia positive semidefinite (Clarabel).

    minimise 1/2 x^T H x - q^T x   over x = [pi (10 nb), phi (n_extra)]
    subject to  pseudo_inertia(pi_b) PSD for every body b,  phi >= lower,  G pi >= h

The pseudo-inertia is linear in pi (inertial.py), so this is a quadratic program over a product of
4x4 PSD cones, a box and linear rows (G pi >= h: the plausibility bounds of plausible_bounds.py): Clarabel, an interior-point conic solver (the default of cvxpy), solves it
to its tolerance in about ten iterations. The variables are scaled by H's diagonal first, because
the inertial parameters span several orders of magnitude. Clarabel's answer may lie a rounding
error outside a cone; each body's pseudo-inertia is therefore clipped to its nearest PSD matrix, so
every returned body passes the PSD test whatever the solver's tolerance. When the unconstrained minimiser
already satisfies every constraint it is returned as it is (exact, no interior-point margin).
(An ADMM written for robocal was used before: slow, and at weak priors its residual-based stopping
test accepted points far from the optimum; docs/dynamics_tiago.md.)
"""
from __future__ import annotations

from dataclasses import dataclass

import clarabel
import numpy as np
import scipy.sparse as sp

from robocal.dynamics.inertial import is_physically_consistent, params_from_pseudo_inertia, pseudo_inertia
from robocal.errors import RobocalError

#: upper triangle of a 4x4 matrix stacked by columns: Clarabel's order for its PSD triangle cone
_UPPER = [(i, j) for j in range(4) for i in range(j + 1)]


def svec(J: np.ndarray) -> np.ndarray:
    """Clarabel's 10 coordinates of a symmetric 4x4 (off-diagonal entries x sqrt 2)."""
    return np.array([J[i, j] * (1.0 if i == j else np.sqrt(2.0)) for i, j in _UPPER])


#: pi (10) -> svec(pseudo-inertia) (10), linear
TO_SVEC = np.column_stack([svec(pseudo_inertia(e)) for e in np.eye(10)])


@dataclass
class PsdQpResult:
    """x: the solution (every body realisable); iterations of the interior-point method; status:
    Clarabel's word for the outcome; converged: it reached its tolerance."""

    x: np.ndarray
    iterations: int
    status: str
    converged: bool


def solve_psd_qp(H: np.ndarray, q: np.ndarray, n_bodies: int, lower: np.ndarray,
                 free_bodies: tuple[int, ...] = (), G: np.ndarray | None = None,
                 h: np.ndarray | None = None) -> PsdQpResult:
    """Minimise 1/2 x^T H x - q^T x with the constraints of the module docstring.
    lower: (n_extra,) bounds on phi (-inf where free); free_bodies: bodies left without their PSD
    constraint (constraint_cost.py asks what each constraint costs); G (m, 10 n_bodies), h (m,): linear rows."""
    n = H.shape[0]
    n_in = 10 * n_bodies
    G = np.zeros((0, n_in)) if G is None else np.asarray(G, float)
    h = np.zeros(0) if h is None else np.asarray(h, float)
    constrained = [b for b in range(n_bodies) if b not in free_bodies]
    inside = unconstrained_if_feasible(H, q, constrained, lower, G, h)
    if inside is not None:        # the constraints are not active: the exact optimum, no interior-point margin
        return PsdQpResult(inside, 0, "Solved", True)
    diag = np.diag(H).copy()
    diag[diag <= 0] = 1.0
    d = 1.0 / np.sqrt(diag)                  # x = d * y: y's quadratic form has a unit diagonal
    blocks, rhs, cones = [], [], []
    bounded = np.flatnonzero(np.isfinite(lower))
    if len(bounded):                         # s = y_k d_k - lower_k >= 0
        A = np.zeros((len(bounded), n))
        A[np.arange(len(bounded)), n_in + bounded] = -1.0
        blocks.append(A)
        rhs.append(-lower[bounded])
        cones.append(clarabel.NonnegativeConeT(len(bounded)))
    if len(h):                               # s = G x - h >= 0
        A = np.zeros((len(h), n))
        A[:, :n_in] = -G
        blocks.append(A)
        rhs.append(-h)
        cones.append(clarabel.NonnegativeConeT(len(h)))
    for b in constrained:                    # s = svec(pseudo_inertia(pi_b)) in the PSD cone
        A = np.zeros((10, n))
        A[:, 10 * b:10 * b + 10] = -TO_SVEC
        blocks.append(A)
        rhs.append(np.zeros(10))
        cones.append(clarabel.PSDTriangleConeT(4))
    A = np.vstack(blocks) * d[None, :]
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    # tighter than the defaults (1e-8): an optimum a few 1e-5 from a cone's boundary (a thin body)
    # otherwise keeps the central path's margin in its last digits
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-8
    solver = clarabel.DefaultSolver(sp.csc_matrix(np.triu(H * d[:, None] * d[None, :])), -q * d,
                                    sp.csc_matrix(A), np.concatenate(rhs), cones, settings)
    sol = solver.solve()
    status = str(sol.status).rsplit(".", 1)[-1]
    x = np.asarray(sol.x, float) * d
    if not np.all(np.isfinite(x)):
        raise RobocalError(f"the consistent fit failed (Clarabel status {status})")
    for b in constrained:
        x[10 * b:10 * b + 10] = nearest_realisable(x[10 * b:10 * b + 10])
    x[n_in:] = np.maximum(x[n_in:], lower)
    return PsdQpResult(x, int(sol.iterations), status, status == "Solved")


def unconstrained_if_feasible(H: np.ndarray, q: np.ndarray, bodies: list[int], lower: np.ndarray,
                              G: np.ndarray | None = None, h: np.ndarray | None = None) -> np.ndarray | None:
    """The unconstrained minimiser H^-1 q when it satisfies every constraint (the PSD test on `bodies`, the
    linear rows G pi >= h), else None."""
    try:
        x = np.linalg.solve(H, q)
    except np.linalg.LinAlgError:
        return None
    n_in = len(x) - len(lower)
    if not np.all(np.isfinite(x)) or np.any(x[n_in:] < lower):
        return None
    if G is not None and len(G) and np.any(G @ x[:n_in] < h):
        return None
    # strict (rtol 0): this point is returned without the projection the solver's answer gets
    if not all(is_physically_consistent(x[10 * b:10 * b + 10], rtol=0.0) for b in bodies):
        return None
    return x


def nearest_realisable(p: np.ndarray) -> np.ndarray:
    """The body whose pseudo-inertia is the nearest PSD matrix to p's (eigenvalues clipped at 0)."""
    eig, vec = np.linalg.eigh(pseudo_inertia(p))
    return params_from_pseudo_inertia((vec * np.maximum(eig, 0.0)) @ vec.T)
