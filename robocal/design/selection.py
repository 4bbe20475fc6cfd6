"""Experiment design: choose which of many candidate poses to measure.

The Jacobian of all candidates is computed once (`DesignMatrix.from_problem`: one Problem over every
candidate, each candidate one sample). Selection then only moves blocks of rows in and out of the
information matrix M = sum_k B_k^T B_k:

1. Columns: the parameters identifiable from ALL candidates (`select_base_parameters`), each scaled by
   its RMS effect per candidate, so that a metre and a radian weigh alike in the spectral criteria
   (D-optimality does not depend on this scaling).
2. Greedy start: add the candidate that maximises D (on M + delta I) until M has full rank (the
   sigma_min-based criteria are flat, hence blind, while M is singular), then the requested criterion.
3. Exchange (Fedorov/DETMAX style): for each chosen pose in turn, swap it for the outside candidate
   that improves the criterion most; repeat sweeps until no swap helps.

Both steps pick the first maximum (lowest candidate index), so the result only depends on the
candidates and their order: the same seed gives the same poses on every run.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from robocal.design import criteria as dc
from robocal.errors import InputError
from robocal.estimation.identifiability import BaseSelection, select_base_parameters
from robocal.design.simulate import simulate_measurements

log = logging.getLogger(__name__)

#: regularisation of M during the greedy start, relative to one candidate's average information
RIDGE = 1e-8
#: M counts as full rank when lambda_min / lambda_max exceeds this (sigma ratio 1e-6)
FULL_RANK = 1e-12


@dataclass
class DesignMatrix:
    """The stacked unit-variance Jacobian of all candidates, split into one row block per candidate.

    names     free parameter names (columns of J)
    J         (m, n) rows scaled to unit variance (row / sigma)
    units     row indices of each candidate (one candidate = one sample of the source problem)
    fixed     row indices always present (priors)
    labels    sample index in the source problem of each candidate
    base      identifiability over all candidates (+ fixed rows)
    """

    names: list[str]
    J: np.ndarray
    units: list[np.ndarray]
    fixed: np.ndarray
    labels: np.ndarray
    base: BaseSelection
    scale: np.ndarray = field(init=False)      # column scale of the base columns (RMS per candidate)
    blocks: np.ndarray = field(init=False)     # (K, min(d_max, L), L) scaled blocks, zero-padded (R of a tall one)
    rows: np.ndarray = field(init=False)       # (K,) true rows per block

    def __post_init__(self):
        cols = self.base.independent
        Jb = self.J[:, cols]
        self.scale = np.sqrt(np.sum(Jb ** 2, axis=0) / max(len(self.units), 1))
        self.scale[self.scale == 0] = 1.0
        self.rows = np.array([len(u) for u in self.units], dtype=int)
        d = int(self.rows.max()) if len(self.rows) else 0
        self.blocks = np.zeros((len(self.units), d, len(cols)))
        for k, u in enumerate(self.units):
            self.blocks[k, :len(u)] = Jb[u] / self.scale
        if d > len(cols):
            # every criterion and update uses a block only through B^T B: a tall block (a camera image's corners:
            # 108 rows for 25 columns) is replaced by the R of its QR (R^T R = B^T B), so the updates work on L x L
            self.blocks = np.linalg.qr(self.blocks, mode="r")
        self.fixed_information = (Jb[self.fixed] / self.scale).T @ (Jb[self.fixed] / self.scale)

    # ---- construction ---------------------------------------------------------------------
    @classmethod
    def from_problem(cls, problem, rtol: float = 1e-8, predict_measurements: bool = True) -> "DesignMatrix":
        """One candidate per sample of `problem` (anything with evaluate(), residuals, params).

        predict_measurements: first replace the observed measurements by their noise-free prediction
        (`nominal_measurements`): a plan has no data yet, and the Jacobian of a rotation residual
        depends on the measured rotation.
        The rows of a term are contiguous and `Evaluation.group` numbers the terms in residual order,
        then the priors; so each row's sample is known without re-evaluating anything.
        """
        unreachable = nominal_measurements(problem) if predict_measurements else set()
        ev = problem.evaluate()
        term_sample = []
        for res in problem.residuals:
            for k in range(res.n_terms):
                s = res.term_samples(k)
                if len(s) != 1:
                    raise InputError(f"measurement '{res.name}' has terms spanning several samples; pose "
                                     "selection needs one sample per term", field=res.name)
                term_sample.append(s[0])
        term_sample = np.array(term_sample, dtype=int)
        is_term = ev.group < len(term_sample)
        row_sample = np.full(len(ev.group), -1)
        row_sample[is_term] = term_sample[ev.group[is_term]]
        labels = np.array([s for s in np.unique(row_sample[is_term]) if s not in unreachable], dtype=int)
        units = [np.flatnonzero(row_sample == s) for s in labels]
        return cls.from_rows(ev.J, list(problem.params.free_names), units, np.flatnonzero(~is_term), labels, rtol)

    @classmethod
    def from_rows(cls, J, names, units, fixed=(), labels=None, rtol: float = 1e-8) -> "DesignMatrix":
        """From any unit-variance Jacobian whose rows are grouped into candidates (any Jacobian source)."""
        J = np.asarray(J, dtype=float)
        units = [np.asarray(u, dtype=int) for u in units]
        fixed = np.asarray(fixed, dtype=int)
        labels = np.arange(len(units)) if labels is None else np.asarray(labels)
        if not len(units):
            raise InputError("no candidate poses to choose from", field="candidates")
        if not np.all(np.isfinite(J)):
            raise InputError("the Jacobian of the candidates is not finite (singular or unreachable poses?)",
                             field="candidates")
        used = np.concatenate(units + [fixed])
        base = select_base_parameters(J[used], list(names), rtol)
        return cls(list(names), J, units, fixed, labels, base)

    # ---- information ------------------------------------------------------------------------
    @property
    def n_candidates(self) -> int:
        return len(self.units)

    @property
    def base_names(self) -> list[str]:
        return [self.names[i] for i in self.base.independent]

    def information(self, chosen) -> np.ndarray:
        """Scaled information matrix of the chosen candidates plus the fixed rows."""
        B = self.blocks[np.asarray(chosen, dtype=int)]
        return self.fixed_information + np.einsum("kdi,kdj->ij", B, B)

    def n_rows(self, chosen) -> int:
        return int(self.rows[np.asarray(chosen, dtype=int)].sum() + len(self.fixed))

    def rows_of(self, chosen) -> np.ndarray:
        return np.concatenate([self.units[k] for k in chosen] + [self.fixed]).astype(int)

    def criteria(self, chosen, W: np.ndarray | None = None) -> dict[str, float]:
        return dc.all_criteria(self.information(chosen), self.n_rows(chosen), W)

    def scaled_weight(self, W: np.ndarray) -> np.ndarray:
        """A weight matrix on all free columns (SI) -> on the scaled base columns."""
        cols = self.base.independent
        return W[np.ix_(cols, cols)] / np.outer(self.scale, self.scale)


class _NoNoise:
    """Stands in for a random generator: every draw is its mean (noise-free simulation)."""

    @staticmethod
    def normal(loc=0.0, scale=1.0, size=None):
        return np.broadcast_to(np.asarray(loc, dtype=float) + 0.0 * np.asarray(scale, dtype=float),
                               np.broadcast_shapes(np.shape(loc), np.shape(scale)) if size is None else size).copy()


def nominal_measurements(problem) -> set[int]:
    """Set every observed residual's measurements to the prediction at the current parameters, and move
    every contact-type candidate (plane, sphere, cylinder, laser line) onto its contact on the nominal
    model. Returns the candidates that cannot reach their contact (to be left out)."""
    return simulate_measurements(problem, problem.params, _NoNoise(), skip_unreachable=True)


@dataclass
class Identifiability:
    """What a pose set can determine, against what all candidates could."""

    selection: BaseSelection        # over all free parameters, on the chosen rows
    unidentifiable: list[str]       # identifiable from the candidates but not from this set
    structural: list[str]           # not identifiable even from all candidates (fixed in a calibration)
    explanation: list[str]          # one sentence per unidentifiable parameter

    @property
    def ok(self) -> bool:
        return not self.unidentifiable


def assess(design: DesignMatrix, chosen, rtol: float | None = None) -> Identifiability:
    """Which parameters a set of chosen candidates leaves undetermined, by name."""
    rows = design.rows_of(chosen)
    sel = select_base_parameters(design.J[rows], design.names, design.base.rtol if rtol is None else rtol)
    dropped = set(sel.dependent)
    lost = [j for j in design.base.independent if j in dropped]
    text = {line.split(" ", 1)[0]: line for line in sel.describe()}
    names = [design.names[j] for j in lost]
    return Identifiability(sel, names, [design.names[j] for j in design.base.dependent],
                           [text.get(n, f"{n} is not determined") for n in names])


@dataclass
class PoseSelection:
    """Result of `select_poses`.

    chosen    candidate indices (into the DesignMatrix), in selection order
    labels    the source problem's sample index of each chosen candidate
    values    every criterion of the final set
    greedy_value / exchanges / sweeps: how the search went
    """

    criterion: str
    chosen: np.ndarray
    labels: np.ndarray
    value: float
    values: dict[str, float]
    greedy_value: float
    exchanges: int
    sweeps: int
    identifiability: Identifiability


def _best_add(design, criterion, M, m, W, candidates, ridge) -> tuple[int, float]:
    """(candidate index, criterion value) of the best block to add to M among `candidates`."""
    k, value = dc.best_addition(criterion, M + ridge, m, design.blocks[candidates], design.rows[candidates], W)
    return int(candidates[k]), value


def select_poses(design: DesignMatrix, n: int, criterion: str = "D", W: np.ndarray | None = None,
                 max_sweeps: int = 50, rtol: float = 1e-9, start=None) -> PoseSelection:
    """Choose `n` candidates maximising `criterion` (see robocal.design.criteria).

    W  weight matrix for the I criterion, on all free columns in SI units (see
       robocal.design.prediction.position_weight); ignored otherwise.
    start  optional initial candidate indices (skips the greedy step).
    """
    if criterion not in dc.CRITERIA:
        raise InputError(f"unknown criterion '{criterion}' (known: {', '.join(dc.CRITERIA)})", field="criterion")
    if criterion == "I" and W is None:
        raise InputError("the I criterion needs validation configurations (a weight matrix)", field="criterion")
    K = design.n_candidates
    if not 1 <= n <= K:
        raise InputError(f"cannot choose {n} poses from {K} candidates", field="N")
    Ws = design.scaled_weight(W) if W is not None else None
    L = len(design.base.independent)
    ridge = RIDGE * np.eye(L)
    chosen = list(start) if start is not None else _greedy(design, n, criterion, Ws, ridge)
    greedy_value = dc.evaluate(criterion, design.information(chosen) + ridge, design.n_rows(chosen), Ws)
    chosen, exchanges, sweeps = _exchange(design, chosen, criterion, Ws, ridge, max_sweeps, rtol)
    chosen = np.array(chosen, dtype=int)
    M = design.information(chosen)
    values = dc.all_criteria(M, design.n_rows(chosen), Ws)
    ident = assess(design, chosen)
    if not ident.ok:
        log.warning("the chosen %d poses leave %s undetermined", n, ", ".join(ident.unidentifiable))
    return PoseSelection(criterion, chosen, design.labels[chosen], values.get(criterion, np.nan), values,
                         greedy_value, exchanges, sweeps, ident)


def greedy_order(design: DesignMatrix, n: int, criterion: str = "D", W: np.ndarray | None = None) -> np.ndarray:
    """The first `n` candidates of the greedy step of `select_poses`, in the order it picks them. Each pick
    depends only on the picks before it, so `select_poses(design, k, ..., start=greedy_order(design, n)[:k])`
    for k <= n is select_poses(design, k, ...) exactly: one greedy run serves every count of an accuracy curve."""
    if not 1 <= n <= design.n_candidates:
        raise InputError(f"cannot choose {n} poses from {design.n_candidates} candidates", field="N")
    ridge = RIDGE * np.eye(len(design.base.independent))
    return np.array(_greedy(design, n, criterion, design.scaled_weight(W) if W is not None else None, ridge), int)


def _greedy(design, n, criterion, Ws, ridge) -> list[int]:
    chosen: list[int] = []
    free = np.ones(design.n_candidates, bool)
    M = design.information([])
    full_rank = False
    for _ in range(n):
        crit = criterion if full_rank else "D"
        k, _ = _best_add(design, crit, M, design.n_rows(chosen), Ws, np.flatnonzero(free), ridge)
        chosen.append(k)
        free[k] = False
        M = M + design.blocks[k].T @ design.blocks[k]
        lam = np.linalg.eigvalsh(M)
        full_rank = full_rank or (lam[-1] > 0 and lam[0] > FULL_RANK * lam[-1])
    return chosen


def _exchange(design, chosen, criterion, Ws, ridge, max_sweeps, rtol):
    chosen = list(chosen)
    inside = np.zeros(design.n_candidates, bool)
    inside[chosen] = True
    m = design.n_rows(chosen)
    M = design.information(chosen)
    current = dc.evaluate(criterion, M + ridge, m, Ws)
    exchanges = sweeps = 0
    for sweeps in range(1, max_sweeps + 1):
        improved = False
        for pos in range(len(chosen)):
            j = chosen[pos]
            Bj = design.blocks[j]
            Mj = M - Bj.T @ Bj
            outside = np.flatnonzero(~inside)
            if not len(outside):
                break
            k, value = _best_add(design, criterion, Mj, m - design.rows[j], Ws, outside, ridge)
            if value > current + rtol * abs(current) + 1e-300:
                chosen[pos] = k
                inside[j], inside[k] = False, True
                M = Mj + design.blocks[k].T @ design.blocks[k]
                m = m - design.rows[j] + design.rows[k]
                current = value
                exchanges += 1
                improved = True
        if not improved:
            break
    return chosen, exchanges, sweeps
