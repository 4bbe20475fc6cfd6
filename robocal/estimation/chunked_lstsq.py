"""Least squares past memory: the R factor of [J r] accumulated a chunk of samples at a time.

A million 6D poses give a 6,000,000 x n Jacobian (2.3 GB at 48 parameters). The solver only ever needs the
(n+1) x (n+1) triangle T of [J r] (robocal.estimation.solve): with [J r] = Q T, stacking a new block under
T and factoring again gives the triangle of all rows so far, so the Jacobian is never held whole. Memory
then grows with the residual vector (8 bytes a row) and one chunk, not with the Jacobian.

Use `evaluate_chunked(problem)` as the solver's `fun`: its J is a `ChunkedJacobian`, whose `triangle(w)`
reuses the triangle made during the evaluation when all weights are 1 (the linear loss) and evaluates the
chunks once more with the robust weights otherwise.
"""
from __future__ import annotations

import numpy as np

from robocal.estimation.problem import Evaluation, Problem
from robocal.estimation.solve import r_factor

CHUNK_TERMS = 20_000


def stack_triangle(T: np.ndarray, block: np.ndarray) -> np.ndarray:
    """Triangle of [T; block] ((n+1) x (n+1))."""
    return r_factor(np.vstack([T, block]), overwrite=True)


class ChunkedJacobian:
    """The Jacobian of `problem` at free values x, kept as the triangle of [J r] (see module doc)."""

    def __init__(self, problem: Problem, x: np.ndarray, chunk_terms: int, shape: tuple[int, int],
                 unweighted: np.ndarray):
        self.problem, self.x, self.chunk_terms, self.shape = problem, np.array(x), chunk_terms, shape
        self.unweighted = unweighted

    def triangle(self, weights: np.ndarray | None = None) -> np.ndarray:
        if weights is None or np.all(weights == 1.0):
            return self.unweighted
        self.problem.params.set_free_values(self.x)
        T = np.zeros((0, self.shape[1] + 1))
        for rows, r, _raw, _group, J in self.problem.pieces(True, self.chunk_terms):
            w = weights[rows]
            T = stack_triangle(T, np.column_stack([J * w[:, None], r * w]))
        return T


def evaluate_chunked(problem: Problem, chunk_terms: int = CHUNK_TERMS) -> Evaluation:
    """problem.evaluate() with J a ChunkedJacobian: r, raw and group whole, the Jacobian as its triangle."""
    problem.blocks = problem.layout()
    m = problem.blocks[-1].rows.stop if problem.blocks else 0
    n = len(problem.params.free_names)
    r, raw, group = np.empty(m), np.empty(m), np.empty(m, int)
    T = np.zeros((0, n + 1))
    for rows, r_k, raw_k, group_k, J in problem.pieces(True, chunk_terms):
        r[rows], raw[rows], group[rows] = r_k, raw_k, group_k
        T = stack_triangle(T, np.column_stack([J, r_k]))
    if len(T) < n + 1:
        T = np.vstack([T, np.zeros((n + 1 - len(T), n + 1))])
    J = ChunkedJacobian(problem, problem.params.free_values(), chunk_terms, (m, n), T)
    return Evaluation(r, J, raw, group)
