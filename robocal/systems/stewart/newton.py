"""Newton-Raphson on the normal equations with a finite-difference Hessian (the Stewart patent's Eqs. 5-8).

F = sum r^2 over the problem's scaled rows. Each iteration solves a dx = -c with c = dF/dx = 2 J^T r and
a = d2F/dx2 = 2 (J^T J + sum_k r_k d2r_k/dx2); the second derivatives are central differences of the
analytic Jacobian with step e (Eq. 8 applied to Eq. 7's derivative, which robocal has exactly).
Levenberg-Marquardt (robocal.estimation.solve) is the default solver; this one is here to reproduce the method of
the source and to cross-check it.

Safeguards (docs/stewart_calibration.md): from the spec's 1 mm set-up the full Hessian a is not positive
definite at the start (the r d2r term dominates the weak directions of a 6-pose design) and the pure
Newton step overshoots. So (1) a is shifted by mu I until it is positive definite (Cholesky succeeds),
(2) the step is halved until F decreases (backtracking line search), and (3) a step at which some pose's
loops cannot be assembled counts as not decreasing F (halved too). Near the solution mu = 0 and the full
step is accepted, so the quadratic rate of the patent's iteration is kept.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robocal.errors import AssemblyError
from robocal.estimation.problem import Problem


@dataclass
class NewtonResult:
    x: np.ndarray
    converged: bool
    iterations: int
    F: list[float] = field(default_factory=list)   # F at the start and after every iteration
    unassemblable: int = 0     # trial steps of the line search at which some pose's loops could not close


MAX_HALVINGS = 30


def _newton_step(a: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve (a + mu I) dx = rhs with the smallest mu in {0, 1e-12, 1e-11, ...} * max|diag a| that makes
    the matrix positive definite: a descent direction even where the Hessian is indefinite."""
    scale = max(float(np.max(np.abs(np.diag(a)))), 1e-300)
    for mu in [0.0] + [scale * 10.0 ** k for k in range(-12, 3)]:
        try:
            L = np.linalg.cholesky(a + mu * np.eye(len(a)))
        except np.linalg.LinAlgError:
            continue
        return np.linalg.solve(L.T, np.linalg.solve(L, rhs))
    return rhs / scale                              # steepest descent, scaled


def patent_newton(problem: Problem, e: float = 1e-6, max_iterations: int = 20, xtol: float = 1e-13,
                  safeguarded: bool = True) -> NewtonResult:
    """Minimise F over the problem's free parameters in place (SI units; e in the parameters' units).
    safeguarded=False takes the patent's literal full Newton step (no shift, no line search)."""
    params = problem.params
    x = params.free_values()
    history = []
    broken = 0
    for it in range(1, max_iterations + 1):
        params.set_free_values(x)
        ev = problem.evaluate()
        r, J = ev.r, ev.J
        history.append(float(r @ r))
        if len(history) > 1 and history[-1] > 0.5 * history[-2] and history[-1] < 1e-6 * history[0]:
            # at the rounding floor (loop assembly, floating point): Newton no longer gains anything
            return NewtonResult(x, True, it - 1, history, broken)
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
        dx = _newton_step(a, -2.0 * J.T @ r) if safeguarded else np.linalg.solve(a, -2.0 * J.T @ r)
        for _ in range(MAX_HALVINGS if safeguarded else 0):            # backtracking: accept the first step that lowers F
            params.set_free_values(x + dx)
            try:
                r_new = problem.evaluate(jacobian=False).r
            except AssemblyError:          # a step so long that some pose's loops no longer close: shorter
                broken += 1
                dx = 0.5 * dx
                continue
            if r_new @ r_new < history[-1]:
                break
            dx = 0.5 * dx
        x = x + dx
        if np.linalg.norm(dx) <= xtol * (1.0 + np.linalg.norm(x)):
            params.set_free_values(x)
            history.append(float(problem.evaluate(jacobian=False).r @ problem.evaluate(jacobian=False).r))
            return NewtonResult(x, True, it, history, broken)
    params.set_free_values(x)
    r = problem.evaluate(jacobian=False).r
    history.append(float(r @ r))
    return NewtonResult(x, False, max_iterations, history, broken)
