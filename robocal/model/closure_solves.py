"""Solves with stacks of closure Jacobians C_s (robocal.model.closed_chain_batch): the damped Newton step of an
assembly, and C_s^-1 for the implicit-function sensitivities with its singularity check.

Each takes C_s's block structure when it has one (a 6-UPS arrow: robocal.model.point_closure_solve, or its numba
kernels, robocal.model.closed_chain_compiled) and the dense LU where that breaks down (a singular block or Schur
complement), so the answers are the LU's and the errors those of `robocal.model.loops.assemble`.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import AssemblyError

SINGULAR_RCOND = 1e-5    # assemble's default: smallest / largest singular value of C_s at the solution
NEGLIGIBLE_DAMPING = 1e-20   # |c|^2 below which the damped step is the Newton step to rounding


def damped_step(A: np.ndarray, r: np.ndarray, mu: np.ndarray, arrow=None, compiled=None) -> np.ndarray:
    """damped_newton's step -(A^T A + mu I)^-1 A^T r (mu = |r|^2) for the stack; the plain Newton step once mu
    is negligible. Through C_s's block structure (`arrow`, its kernels `compiled`) when it has one (the dense LU
    where its eliminations break down: a singular block or S)."""
    ns = A.shape[2]
    plain = A.shape[1] == ns and mu.max() < NEGLIGIBLE_DAMPING
    if arrow is not None and compiled is not None:     # NaN where an elimination breaks down
        step = compiled.newton_step(A, r) if plain else compiled.damped_step(A, r, mu)
        if np.isfinite(step).all():
            return step
    elif arrow is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            try:
                step = arrow.newton_step(A, r) if plain else arrow.damped_step(A, r, mu)
            except np.linalg.LinAlgError:
                step = None
        if step is not None and np.isfinite(step).all():
            return step
    if plain:
        # mu = |c|^2 < 1e-20: the damped step differs from the Newton step -C_s^-1 c by mu / s_min^2 of
        # itself, ~1e-25 m or rad for a Stewart platform's C_s (s_min ~ 0.1): solve C_s directly
        return -np.linalg.solve(A, r[:, :, None])[:, :, 0]
    normal = np.swapaxes(A, 1, 2) @ A
    normal[:, np.arange(ns), np.arange(ns)] += mu[:, None]
    return -np.linalg.solve(normal, np.einsum("nmi,nm->ni", A, r)[:, :, None])[:, :, 0]


def inverse(A: np.ndarray, arrow=None):
    """A^-1 for the stack (through C_s's block structure when it has one: square C_s only), None where the
    LU breaks down."""
    if arrow is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            try:
                inv = arrow.inverse(A)
            except np.linalg.LinAlgError:
                inv = None
        if inv is not None and np.isfinite(inv).all():
            return inv
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return None


def sensitivity_solver(Cs: np.ndarray, labels: np.ndarray, arrow=None, compiled=None) -> np.ndarray:
    """(n, n_solved, m): C_s^-1, or (C_s^T C_s)^-1 C_s^T with more rows than unknowns (lstsq's solution);
    raises AssemblyError where C_s is singular, as `assemble` does (exact check on the samples whose
    norm bound on s_min / s_max falls below the threshold; `labels`: the block's sample indices)."""
    square = Cs.shape[1] == Cs.shape[2]
    A = Cs if square else np.swapaxes(Cs, 1, 2) @ Cs
    inv = None
    if compiled is not None and arrow is not None:     # NaN where the elimination breaks down
        inv, bound = compiled.inverse(A)
        inv = inv if np.isfinite(inv).all() else None
    if inv is None:
        inv = inverse(A, arrow)
        bound = (1.0 / (np.linalg.norm(A, axis=(1, 2)) * np.linalg.norm(inv, axis=(1, 2))) if inv is not None
                 else np.zeros(len(A)))
    ratio_bound = bound if square else np.sqrt(bound)       # <= s_min / s_max of C_s
    for i in np.flatnonzero(~(ratio_bound >= SINGULAR_RCOND)):
        s = np.linalg.svd(Cs[i], compute_uv=False)
        if s[-1] < SINGULAR_RCOND * max(s[0], 1e-300):
            raise AssemblyError(f"sample {labels[i]}: closed-chain assembly reached a singular configuration "
                                f"(condition number {s[0] / max(s[-1], 1e-300):.3g}); the passive joints are "
                                "not determined by these readings")
    if inv is None:         # the LU broke down on matrices the singular values call regular
        inv = np.linalg.pinv(A)
    return inv if square else inv @ np.swapaxes(Cs, 1, 2)
