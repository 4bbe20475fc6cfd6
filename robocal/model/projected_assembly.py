"""Closed-chain assembly in the lean loop of Pinocchio's closed-loop examples, with robocal's Newton steps and
safety net.

Pinocchio's examples project a configuration onto the constraints with full Gauss-Newton steps dq_s = -J_s^+ c
(c and J from the constraint models, robocal.model.pinocchio_rows). That loop is kept, but its step is robocal's:
damped by mu = |c|^2 as the first trial step of robocal's damped Newton, which keeps the warm start's branch where
the plain step can leave it (from the neutral start of tests/test_closed_chain_batch.py's linkage, the plain step
assembles the arm's distance loop on its other branch); below |c|^2 = 1e-20 the two steps agree to rounding and
the plain one is taken (an LU solve when J_s is square). Each step is kept only if it lowers |c|^2 by the Armijo
fraction; the first that does not (far from the constraint manifold, near a singularity) returns None, and the
caller hands the sample to robocal.model.inverse_kinematics.damped_newton from the same warm start, so its line
search and its errors are unchanged. At the solution J_s's regularity is checked as the damped Newton checks it:
a rigorous bound, 1 / (|J_s|_F |J_s^-1|_F) <= s_min / s_max, clears the common case without an SVD.

These are the steps robocal.model.closed_chain_batch takes on many samples at once. benchmarks/closed_chain_assembly.py
compares the three loops (Pinocchio's plain projection, the damped Newton alone, this one) and the batched path.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from robocal.model.closure_solves import NEGLIGIBLE_DAMPING
from robocal.model.inverse_kinematics import ARMIJO, check_regular, damped_step



def regular_enough(a: np.ndarray, rcond: float) -> bool:
    """True when s_min / s_max of the square `a` is certainly >= rcond (a rigorous, cheaper bound than the SVD)."""
    try:
        inverse = np.linalg.inv(a)
    except np.linalg.LinAlgError:
        return False
    bound = 1.0 / (np.linalg.norm(a) * np.linalg.norm(inverse))
    return bool(np.isfinite(bound) and bound >= rcond)


def projected_newton(rows: Callable, q0: np.ndarray, retract: Callable, free: np.ndarray, tol: float,
                     max_iterations: int, singular_rcond: float | None, label: str, what: str):
    """q with max |c(q)| < tol by full Newton steps, or None where the damped Newton's line search must take over.
    rows(q) -> (c, J); retract(q, dv); free: the solved columns of J. Raises AssemblyError (check_regular) when
    the solution is singular."""
    q = q0
    c, jac = rows(q)
    cost = float(c @ c)
    n = jac.shape[1]
    for _ in range(max_iterations + 1):
        a = jac[:, free]
        if not c.size or np.abs(c).max() < tol:
            if singular_rcond is not None and not (a.shape[0] == a.shape[1] and regular_enough(a, singular_rcond)):
                check_regular(a, singular_rcond, label, what)
            return q
        try:
            if a.shape[0] == a.shape[1] and cost < NEGLIGIBLE_DAMPING:
                step = -np.linalg.solve(a, c)
            else:
                step = damped_step(a, c, cost)
        except np.linalg.LinAlgError:
            return None
        dv = np.zeros(n)
        dv[free] = step
        q_try = retract(q, dv)
        c_try, jac_try = rows(q_try)
        cost_try = float(c_try @ c_try)
        if not cost_try < (1.0 - ARMIJO) * cost:       # also NaN: the damped Newton's line search takes over
            return None
        q, c, jac, cost = q_try, c_try, jac_try, cost_try
    return None
