"""Newton FK of the floating-nut hexapod for many poses at once (FloatingNutKinematics.fk with (N, 6) lengths).

Same iterates as the single-pose solvers (fk.py, fk_compiled.py): a cold start takes the second-order home step
(home_step.py) as its first iteration, then Newton with the analytic matrix of `jacobian` on the samples not yet
converged; a converged sample takes one chord step with its last matrix. See docs/floating_nut_hexapod.md.
"""
from __future__ import annotations

import logging

import numpy as np

from robocal.systems.floating_nut.results import FKNotConverged, wrap_angle
from robocal.systems.floating_nut.vectors import dot

log = logging.getLogger(__name__)


def newton_batch(kin, L, P, cold, compensate, jacobian, tol, max_iter, warn_condition):
    """Solve l_c(P) = L (or l(P) = L) for (N, 6) lengths L from starts P (N, 6), in place.

    Returns (P, iterations (N,), residual (N,), history). Raises FKNotConverged naming the first sample that fails.
    """
    first = 0
    n = L.shape[0]
    iterations = np.zeros(n, dtype=int)
    residual = np.full(n, np.inf)
    history: list[float] = []
    active = np.arange(n)
    J = None
    J_final = np.full((n, 6, 6), np.nan)       # last Newton matrix of each sample
    if cold and jacobian != "fd" and kin.home_step().ready(compensate):
        # cold start: the residual at p0 is L - l0 (theta(p0) = 0); the second-order home step
        # (home_step.py) is the first iteration, and J(p0) the matrix of a chord step right after it
        err = L - kin._l0
        residual[:] = np.max(np.abs(err), axis=1)
        history.append(float(residual.max()))
        active = np.flatnonzero(residual >= tol)
        if active.size and max_iter == 0:
            raise FKNotConverged(f"FK of sample {active[0]} did not converge in 0 iterations (residual "
                                 f"{residual[active[0]]:.3g} m, tolerance {tol:g} m)", sample=int(active[0]))
        P[active] += kin.home_step().steps(err[active], compensate)
        iterations[active] = 1
        J = np.broadcast_to(kin.home_step().jacobian[compensate and jacobian == "full"], (active.size, 6, 6))
        first = 1 if active.size else max_iter + 1
    for k in range(first, max_iter + 1):
        Pa = P[active]
        t = kin._terms(Pa, what="FK iterate of sample")
        model = t.length
        if compensate:
            model = model + kin._gain * wrap_angle(t.phi - kin._phi0)
        err = L[active] - model
        res = np.max(np.abs(err), axis=1)
        residual[active] = res
        history.append(float(res.max()))
        todo = res >= tol
        if J is not None and not np.all(todo):
            # Converged: one chord step with the previous matrix (no new kinematics) takes the
            # pose error from about |J^-1| tol down to round-off.
            done = ~todo
            P[active[done]] += np.linalg.solve(J[done], err[done][..., None])[..., 0]
            J_final[active[done]] = J[done]
        if not np.any(todo):
            break
        if k == max_iter:
            bad = int(active[np.argmax(todo)])
            raise FKNotConverged(f"FK of sample {bad} did not converge in {max_iter} iterations "
                                 f"(residual {residual[bad]:.3g} m, tolerance {tol:g} m)", sample=bad)
        if not np.all(todo):
            active, Pa, t, err = active[todo], Pa[todo], _subset(t, todo), err[todo]
        J = kin._newton_matrix(t, Pa, compensate, jacobian)
        try:
            step = np.linalg.solve(J, err[..., None])[..., 0]
        except np.linalg.LinAlgError as exc:
            raise FKNotConverged(f"FK hit a singular Jacobian at iteration {k} (samples "
                                 f"{active[:5].tolist()}...)", sample=int(active[0])) from exc
        if not np.all(np.isfinite(step)):
            bad = int(active[np.argmax(~np.all(np.isfinite(step), axis=1))])
            raise FKNotConverged(f"FK of sample {bad}: singular Jacobian", sample=bad)
        P[active] += step
        iterations[active] += 1
    if warn_condition is not None:
        evaluated = np.flatnonzero(iterations > 0)
        # cond_2(J) <= |J|_F |J^-1|_F: the exact (SVD, 4 times dearer) cond only above the threshold
        Jf = J_final[evaluated]
        inv = np.linalg.inv(Jf)
        bound = np.sqrt(dot(Jf, Jf).sum(axis=1) * dot(inv, inv).sum(axis=1))
        evaluated, Jf = evaluated[~(bound <= warn_condition)], Jf[~(bound <= warn_condition)]
        if evaluated.size:
            cond = np.linalg.cond(Jf)
            if np.any(cond > warn_condition):
                log.warning("FK: Jacobian condition number %.3g near the solution of sample %d "
                            "(close to a singularity)", cond.max(), int(evaluated[np.argmax(cond)]))
    return P, iterations, residual, history


def _subset(t, mask):
    """The pose terms (kinematics._PoseTerms) of the samples in mask."""
    return type(t)(*(getattr(t, k)[mask] for k in t.__dataclass_fields__))
