"""Least squares past memory: the R factor of [J r] accumulated a chunk of samples at a time.

A million 6D poses give a 6,000,000 x n Jacobian (2.3 GB at 48 parameters). The solver only ever needs the
(n+1) x (n+1) triangle T of [J r] (robocal.estimation.solve): with [J r] = Q T, stacking a new block under
T and factoring again gives the triangle of all rows so far, so the Jacobian is never held whole. Memory
then grows with the residual vector (8 bytes a row) and one chunk, not with the Jacobian.

`evaluator(problem, chunk_terms)` is what calibrate() and its stages evaluate with: problem.evaluate, or,
for a problem too large to hold its Jacobian (more than LARGE_JACOBIAN entries, or chunk_terms > 0),
`evaluate_chunked`, whose J is a `ChunkedJacobian`: `triangle(w, rows)` returns the triangle made during the
evaluation (of all rows, or of the data rows without the priors) when all weights are 1 (the linear loss),
and evaluates the chunks once more with the robust weights otherwise.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from robocal.estimation.problem import EVALUATE_CHUNK_TERMS, Evaluation, Problem
from robocal.estimation.solve import r_factor

CHUNK_TERMS = EVALUATE_CHUNK_TERMS
LARGE_JACOBIAN = 50_000_000     # entries (400 MB): above this calibrate() evaluates in chunks


def stack_triangle(T: np.ndarray, block: np.ndarray) -> np.ndarray:
    """Triangle of [T; block] ((n+1) x (n+1))."""
    return r_factor(np.vstack([T, block]), overwrite=True)


def prior_mask(problem: Problem, m: int) -> np.ndarray:
    """True on the prior rows of the current layout."""
    mask = np.zeros(m, bool)
    for b in problem.blocks:
        if b.type_name == "prior":
            mask[b.rows] = True
    return mask


class ChunkedJacobian:
    """The Jacobian of `problem` at free values x, kept as the triangle of [J r] (see module doc)."""

    def __init__(self, problem: Problem, x: np.ndarray, chunk_terms: int, shape: tuple[int, int],
                 unweighted: np.ndarray, data_unweighted: np.ndarray, data_rows: np.ndarray):
        self.problem, self.x, self.chunk_terms, self.shape = problem, np.array(x), chunk_terms, shape
        self.unweighted, self.data_unweighted, self.data_rows = unweighted, data_unweighted, data_rows

    def triangle(self, weights: np.ndarray | None = None, rows: np.ndarray | None = None) -> np.ndarray:
        """Triangle of [J r] * weights over the rows (a boolean mask; None: all)."""
        unit = weights is None or np.all(weights == 1.0)
        if unit and (rows is None or rows.all()):
            return self.unweighted
        if unit and np.array_equal(rows, self.data_rows):
            return self.data_unweighted
        self.problem.params.set_free_values(self.x)
        T = np.zeros((0, self.shape[1] + 1))
        for piece, r, _raw, _group, J in self.problem.pieces(True, self.chunk_terms):
            w = np.ones(len(r)) if weights is None else weights[piece]
            keep = slice(None) if rows is None else rows[piece]
            T = stack_triangle(T, np.column_stack([J * w[:, None], r * w])[keep])
        return pad(T, self.shape[1] + 1)


def pad(T: np.ndarray, k: int) -> np.ndarray:
    return np.vstack([T, np.zeros((k - len(T), k))]) if len(T) < k else T


def evaluate_chunked(problem: Problem, chunk_terms: int = CHUNK_TERMS) -> Evaluation:
    """problem.evaluate() with J a ChunkedJacobian: r, raw and group whole, the Jacobian as its triangles
    (of the data rows, and of all rows with the priors stacked below)."""
    problem.blocks = problem.layout()
    m = problem.blocks[-1].rows.stop if problem.blocks else 0
    n = len(problem.params.free_names)
    r, raw, group = np.empty(m), np.empty(m), np.empty(m, int)
    priors = prior_mask(problem, m)
    T_data, T_prior = np.zeros((0, n + 1)), np.zeros((0, n + 1))
    for rows, r_k, raw_k, group_k, J in problem.pieces(True, chunk_terms):
        r[rows], raw[rows], group[rows] = r_k, raw_k, group_k
        block = np.column_stack([J, r_k])
        if priors[rows].all():
            T_prior = np.vstack([T_prior, block])
        else:
            T_data = stack_triangle(T_data, block)
    T_all = stack_triangle(T_data, T_prior) if len(T_prior) else T_data
    J = ChunkedJacobian(problem, problem.params.free_values(), chunk_terms, (m, n), pad(T_all, n + 1),
                        pad(T_data, n + 1), ~priors)
    return Evaluation(r, J, raw, group)


def evaluator(problem: Problem, chunk_terms: int | None = None) -> tuple[Callable[[], Evaluation], bool]:
    """(evaluate, chunked): the problem's evaluation for a solver, in chunks when chunk_terms > 0 or when the
    Jacobian would exceed LARGE_JACOBIAN entries (chunk_terms None), whole when chunk_terms is 0."""
    blocks = problem.layout()
    m = blocks[-1].rows.stop if blocks else 0
    large = m * len(problem.params.free_names) > LARGE_JACOBIAN
    chunked = bool(chunk_terms) or (chunk_terms is None and large)
    if not chunked:
        return problem.evaluate, False
    return (lambda: evaluate_chunked(problem, int(chunk_terms or CHUNK_TERMS))), True
