"""Newton-Raphson on the normal equations with a finite-difference Hessian (the Stewart patent's Eqs. 5-8).

F = sum r^2 over the problem's scaled rows. Each iteration solves a dx = -c with c = dF/dx = 2 J^T r and
a = d2F/dx2 = 2 (J^T J + sum_k r_k d2r_k/dx2); the second derivatives are central differences of the
analytic Jacobian with step e (Eq. 8 applied to Eq. 7's derivative, which robocal has exactly).
Levenberg-Marquardt (robocal.estimation.solve) is the default solver; this one is here to reproduce the method of
the source and to cross-check it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robocal.estimation.problem import Problem


@dataclass
class NewtonResult:
    x: np.ndarray
    converged: bool
    iterations: int
    F: list[float] = field(default_factory=list)   # F at the start and after every iteration


def patent_newton(problem: Problem, e: float = 1e-6, max_iterations: int = 20, xtol: float = 1e-13) -> NewtonResult:
    """Minimise F over the problem's free parameters in place (SI units; e in the parameters' units)."""
    params = problem.params
    x = params.free_values()
    history = []
    for it in range(1, max_iterations + 1):
        params.set_free_values(x)
        ev = problem.evaluate()
        r, J = ev.r, ev.J
        history.append(float(r @ r))
        if len(history) > 1 and history[-1] > 0.5 * history[-2] and history[-1] < 1e-6 * history[0]:
            # at the rounding floor (loop assembly, floating point): Newton no longer gains anything
            return NewtonResult(x, True, it - 1, history)
        second = np.zeros((len(x), len(x)))
        for j in range(len(x)):
            Js = []
            for sgn in (0.5, -0.5):
                xs = x.copy()
                xs[j] += sgn * e
                params.set_free_values(xs)
                Js.append(problem.evaluate().J)
            second[:, j] = r @ ((Js[0] - Js[1]) / e)      # sum_k r_k d2r_k / dx_i dx_j
        a = 2.0 * (J.T @ J + 0.5 * (second + second.T))
        dx = np.linalg.solve(a, -2.0 * J.T @ r)
        x = x + dx
        if np.linalg.norm(dx) <= xtol * (1.0 + np.linalg.norm(x)):
            params.set_free_values(x)
            history.append(float(problem.evaluate(jacobian=False).r @ problem.evaluate(jacobian=False).r))
            return NewtonResult(x, True, it, history)
    params.set_free_values(x)
    r = problem.evaluate(jacobian=False).r
    history.append(float(r @ r))
    return NewtonResult(x, False, max_iterations, history)
