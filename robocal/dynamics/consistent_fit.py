"""Physically consistent identification: every body realisable, the CAD values as a prior.

Unknowns: every body's 10 inertial parameters pi and the extra terms phi (friction, offsets, rotor
inertia). The fit minimises
    sum_rows (w (X_in pi + X_ex phi - tau))^2 + lambda (n_rows / n_prior) sum ((pi - pi_cad) / s)^2
subject to every body's pseudo-inertia positive semidefinite (the necessary and sufficient
condition for pi to be a mass distribution), the plausibility bounds when given (each body's mass in a
band around CAD, its mass inside a bounding ellipsoid: plausible_bounds.py) and Coulomb friction, viscous
friction and rotor inertia >= 0. It is convex; psd_qp.py solves it (Clarabel) and returns a point of the constraint set.
s are the CAD body's natural scales (mass m, first moments m l, inertias m l^2, with l the CAD
body's RMS mass distance from its joint, sqrt(tr Sigma / m)); lambda = 1 weighs the prior like the
whole data set; prior_weight.py chooses lambda from the data.
(A log-Cholesky parametrisation (Rucker & Wensing 2022) solved by scipy least_squares was tried
first: when the optimum puts a body on the cone's boundary it needs infinite log values, and it had
not converged after 5000 evaluations on the TIAGo log; see docs/dynamics_tiago.md.)
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from robocal.dynamics.inertial import pseudo_inertia
from robocal.dynamics.plausible_bounds import LinearBounds
from robocal.dynamics.psd_qp import solve_psd_qp
from robocal.dynamics.regression import Regressor, row_weights
from robocal.errors import InputError

NONNEGATIVE_TERMS = ("coulomb", "viscous", "armature", "coulomb_pos", "coulomb_neg", "viscous_pos", "viscous_neg")


@dataclass
class ConsistentFit:
    """inertial (10 nb,) physically consistent parameters; extra (n_extra,) in the regressor's
    column order; prior_weight lambda; iterations of the conic solver; data_cost, prior_cost: the data
    and prior parts of the objective (weighted units); converged: the solver met its tolerance (status:
    its word)."""

    inertial: np.ndarray
    extra: np.ndarray
    prior_weight: float
    iterations: int
    data_cost: float
    converged: bool
    status: str = "Solved"
    prior_cost: float = 0.0
    hessian: np.ndarray | None = field(default=None, repr=False)

    def std(self, noise_variance: float) -> np.ndarray:
        """Standard errors of [inertial, extra] from the objective's curvature (data and prior; the
        constraints, which can only narrow the spread, left out): sqrt(diag(noise_variance H^-1)), with
        noise_variance the weighted residual variance times the filtered noise's inflation."""
        return np.sqrt(np.maximum(np.diag(np.linalg.pinv(self.hessian)), 0.0) * noise_variance)

    @property
    def objective(self) -> float:
        return self.data_cost + self.prior_cost

    @property
    def params(self) -> np.ndarray:
        return np.r_[self.inertial, self.extra]

    def predict(self, reg: Regressor) -> np.ndarray:
        """Joint torques (T, nr) of the identified model on the recorded joints."""
        return (reg.X @ self.params).reshape(-1, len(reg.recorded))


def prior_scales(cad: np.ndarray) -> np.ndarray:
    """Per-parameter scales s (10 nb,) from the CAD bodies (see module docstring)."""
    cad = np.asarray(cad, float)
    return scales_of(cad.tobytes()).copy()


@lru_cache(maxsize=4)      # an identification fits the same CAD bodies some 25 times
def scales_of(cad_bytes: bytes) -> np.ndarray:
    """prior_scales of the CAD vector given as its float64 bytes (the cache's key)."""
    out = []
    for p in np.frombuffer(cad_bytes).reshape(-1, 10):
        m = max(p[0], 1e-6)
        length = np.sqrt(max(np.trace(pseudo_inertia(p)[:3, :3]) / m, 1e-6))
        out.append(np.r_[m, np.full(3, m * length), np.full(6, m * length**2)])
    return np.concatenate(out)


def fit_consistent(reg: Regressor, tau: np.ndarray, sigma: np.ndarray, cad: np.ndarray,
                   prior_weight: float, free_bodies: tuple[int, ...] = (),
                   free_terms: tuple[str, ...] = (), bounds: LinearBounds | None = None,
                   free_rows: tuple[int, ...] = ()) -> ConsistentFit:
    """Consistent fit at one prior weight (psd_qp.py). free_bodies (indices), free_terms (extra column
    names) and free_rows (rows of `bounds`) are left without their constraint: constraint_cost.py's question."""
    tau = np.asarray(tau, float)
    n_in = reg.n_inertial
    if len(cad) != n_in:
        raise InputError(f"CAD parameters have {len(cad)} values, the regressor {n_in}", field="inertial")
    w = row_weights(sigma, len(tau))
    A = reg.X * w[:, None]
    y = tau.reshape(-1) * w
    names = reg.names[n_in:]
    lower = np.array([0.0 if n.rsplit(".", 1)[-1] in NONNEGATIVE_TERMS and n not in free_terms else -np.inf
                      for n in names])
    prior = np.r_[(len(y) / n_in) * prior_weight / prior_scales(cad) ** 2, np.zeros(len(names))]
    H = A.T @ A + np.diag(prior)
    q = A.T @ y + prior * np.r_[cad, np.zeros(len(names))]
    G = h = None
    if bounds is not None and len(bounds):
        keep = [i for i in range(len(bounds)) if i not in free_rows]
        G, h = bounds.G[keep], bounds.h[keep]
    sol = solve_psd_qp(H, q, n_in // 10, lower, free_bodies, G, h)
    data_cost = float(np.sum((A @ sol.x - y) ** 2))
    prior_cost = float(np.sum(prior[:n_in] * (sol.x[:n_in] - cad) ** 2))
    return ConsistentFit(sol.x[:n_in], sol.x[n_in:], float(prior_weight), sol.iterations, data_cost,
                         sol.converged, sol.status, prior_cost, H)
