"""Model-selection criteria from one fit, without refits (docs/validation.md, "Choosing a model").

`linearise(problem)` takes a fitted problem's scaled residual and Jacobian at its current values, with what
each row is (the sample it belongs to, its block, its unit, its scale back to SI). From it:

- `approximate_loo(lin, folds)`: the held-out residual of every data row, each fold (a set of samples, by
  default every sample alone) predicted by the fit without it. For a fit that is linear in its parameters
  this is exact (the block form of the PRESS residual, e_G = (I - H_GG)^-1 r_G with H = J (J^T J)^-1 J^T,
  prior rows kept in J^T J and never held out); for a calibration it is the first-order version of
  brute-force cross-validation, at the cost of one factorisation.
- `information_criteria(lin)`: AIC, BIC, Akaike's final prediction error (the expected error at the same
  postures with new noise), GCV, with the effective number of parameters (the trace of the hat matrix over
  the data rows: priors shrink it).
- `log_evidence(J, y, prior_sigma)`: the log marginal likelihood of the linear Gaussian model y = J d + e,
  d_j ~ N(0, prior_sigma_j^2) (inf: a flat prior, projected out), e ~ N(0, s2 I), maximised over s2.
  `nominal_evidence(problem, options)` is the evidence of a model about its registered nominal, with the
  physically scaled prior on every robot parameter at the strengths the evidence prefers (one per scale
  family, as calibrate's default prior).

Every error figure is the norm of a 3D point (mm) or orientation (mrad), as elsewhere in robocal.
Robust losses are ignored (the criteria read the plain linearisation).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from robocal.estimation.calibrate import CalibrationOptions
from robocal.estimation.cross_validation import RANGE_MARGIN, range_excess
from robocal.estimation.physical_scale import physical_scales
from robocal.estimation.prediction_errors import GROUP
from robocal.estimation.problem import Problem
from robocal.estimation.regularisation import RANK_TOL, STRENGTHS, evidence_basis, family_strengths, project_out
from robocal.estimation.registration import register_nominal

UNIT_TO_REPORT = {"length": 1e3, "angle": 1e3}     # SI -> mm, mrad (pixels stay px)
SINGULAR = 1e-10       # a fold whose (I - H_GG) has a pivot this small leaves a parameter undetermined


@dataclass
class Linearised:
    """A fitted problem's rows at its current values. Data rows first, then prior rows."""

    names: list[str]            # the free parameters (columns of J)
    J: np.ndarray               # (m, n) Jacobian of the scaled residual
    r: np.ndarray               # (m,) scaled residual (unit variance at the stated sigmas)
    data: np.ndarray            # (m,) True for a measurement row, False for a prior row
    sample: np.ndarray          # (m,) sample of a data row (-1: prior row)
    scale: np.ndarray           # (m,) raw SI residual = r / scale on data rows (1 on prior rows)
    kind: np.ndarray            # (m,) 'length' / 'angle' / 'prior'
    quantity: np.ndarray        # (m,) id of the 3D point / orientation a row belongs to (or of the row alone)
    part: np.ndarray            # (m,) index of that point / orientation within its term (rigid_points: the point)
    block: np.ndarray           # (m,) block name

    @property
    def n_data(self) -> int:
        return int(self.data.sum())


def linearise(problem: Problem) -> Linearised:
    """The problem's rows and Jacobian at its parameters' current values (after `calibrate`)."""
    ev = problem.evaluate(jacobian=True)
    m = len(ev.r)
    data = np.zeros(m, bool)
    sample, quantity, part = np.full(m, -1), np.arange(m) + 10 ** 9, np.zeros(m, int)   # prior rows: own ids
    scale, kind, block = np.ones(m), np.full(m, "prior", dtype=object), np.full(m, "priors", dtype=object)
    qid = 0
    for res, b in zip(problem.residuals, problem.blocks):
        rs = res.row_scale()
        keep = rs != 0
        units = np.array(res.row_units)[keep]
        n_keep = int(keep.sum())
        start = b.rows.start
        # the rows of one term of one unit kind: triples are 3D points / orientations, pairs image points
        # (prediction_errors.GROUP), else single rows
        per_term = np.zeros(n_keep, int)
        offset = 0
        for u in dict.fromkeys(units):
            idx = np.flatnonzero(units == u)
            g = GROUP.get(u, 3)
            ids = np.arange(len(idx)) // g if len(idx) % g == 0 else np.arange(len(idx))
            per_term[idx] = ids + offset
            offset += ids.max() + 1
        samples = np.asarray(res.samples)
        first = samples if samples.ndim == 1 else samples[:, 0]
        rows = slice(start, start + n_keep * res.n_terms)
        data[rows] = True
        sample[rows] = np.repeat(first, n_keep)
        scale[rows] = np.tile(rs[keep], res.n_terms)
        kind[rows] = np.tile(units, res.n_terms)
        block[rows] = res.name
        quantity[rows] = qid + (np.arange(res.n_terms)[:, None] * offset + per_term[None, :]).ravel()
        part[rows] = np.tile(per_term, res.n_terms)
        qid += offset * res.n_terms
    return Linearised(problem.params.free_names, ev.J, ev.r, data, sample, scale, kind.astype(str), quantity,
                      part, block.astype(str))


def norms(lin: Linearised, raw: np.ndarray, kind: str = "length", block: str | None = None,
          part: int | None = None):
    """(samples, norms in mm or mrad) of the 3D points / orientations of `kind` among the data rows, from a raw
    SI value per data row (e.g. `approximate_loo`'s held-out residuals); `block` limits to one block, `part` to
    one point of each term (a rigid body's first point: 0)."""
    sel = lin.data & (lin.kind == kind)
    if block is not None:
        sel &= lin.block == block
    if part is not None:
        sel &= lin.part == part
    q = lin.quantity[sel]
    ids, inverse = np.unique(q, return_inverse=True)
    sq = np.bincount(inverse, weights=np.asarray(raw)[sel[lin.data]] ** 2, minlength=len(ids))
    first = np.zeros(len(ids), int)
    first[inverse[::-1]] = np.flatnonzero(sel)[::-1]
    return lin.sample[first], np.sqrt(sq) * UNIT_TO_REPORT.get(kind, 1.0)


def inside_others(values: np.ndarray, margin: float = RANGE_MARGIN) -> np.ndarray:
    """(N,) True where a posture lies within the joint ranges of the other postures (widened by `margin`, rad or
    m): leaving it out does not shrink the range the fit covers, so its held-out error is an interpolation."""
    values = np.atleast_2d(np.asarray(values, float))
    out = np.zeros(len(values), bool)
    for i in range(len(values)):
        others = np.delete(values, i, axis=0)
        out[i] = len(others) > 0 and bool(np.all(np.abs(range_excess(others, values[i:i + 1])) <= margin))
    return out


def rms(values: np.ndarray) -> float:
    v = np.asarray(values, float)
    return float(np.sqrt(np.mean(v ** 2))) if len(v) else float("nan")


@dataclass
class HeldOut:
    raw: np.ndarray            # (n_data,) held-out SI residual of every data row (nan: undetermined fold)
    undetermined: list[int]    # folds whose removal leaves a parameter without data (their rows are nan)
    steps: np.ndarray | None = None   # (folds, n) parameter change of each fold's leave-out (with steps=True)


def _factor(J: np.ndarray) -> np.ndarray:
    """Upper triangle R with R^T R = J^T J (full column rank required)."""
    R = scipy.linalg.qr(J, mode="r")[0][: J.shape[1]]
    d = np.abs(np.diag(R))
    if J.shape[1] and d.min() <= RANK_TOL * max(d.max(), 1e-300):
        raise ValueError("the fit's Jacobian is rank deficient: the free parameters are not all determined")
    return R


def approximate_loo(lin: Linearised, folds: list[np.ndarray] | None = None, steps: bool = False) -> HeldOut:
    """Held-out residuals of the linearised fit, each fold (sample indices) left out in turn (see module doc).
    Default folds: every sample alone. A sample in no fold keeps nan. steps: also each fold's parameter change
    d_G = (A^T A - J_G^T J_G)^-1 J_G^T r_G = R^-1 B e_G (Woodbury; e_G the scaled held-out residual), so the
    training rows' residual after the leave-out is r + J d_G (nan for an undetermined fold)."""
    Jd, rd = lin.J[lin.data], lin.r[lin.data]
    R = _factor(lin.J)
    samples = lin.sample[lin.data]
    if folds is None:
        folds = [np.array([s]) for s in np.unique(samples)]
    out = np.full(len(rd), np.nan)
    step = np.zeros((len(folds), lin.J.shape[1])) if steps else None
    bad = []
    for k, fold in enumerate(folds):
        rows = np.flatnonzero(np.isin(samples, fold))
        if not len(rows):
            continue
        # B = R^-T J_G^T, so that H_GG = B^T B
        B = scipy.linalg.solve_triangular(R, Jd[rows].T, trans="T")
        M = np.eye(len(rows)) - B.T @ B
        w, V = np.linalg.eigh(M)
        if w.min() <= SINGULAR:
            bad.append(k)
            if steps:
                step[k] = np.nan
            continue
        e = V @ ((V.T @ rd[rows]) / w)
        out[rows] = e / lin.scale[lin.data][rows]
        if steps:
            step[k] = scipy.linalg.solve_triangular(R, B @ e)
    return HeldOut(out, bad, step)


def effective_parameters(lin: Linearised) -> float:
    """Trace of the hat matrix over the data rows: the number of free parameters, less what priors decide."""
    if not lin.J.shape[1]:
        return 0.0
    B = scipy.linalg.solve_triangular(_factor(lin.J), lin.J[lin.data].T, trans="T")
    return float(np.sum(B * B))


def held_out_norms(problem: Problem, folds: list[np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(samples, norms): the closed-form leave-one-out error of every point (mm) of a fitted problem, each fold
    (default: every sample) predicted by the linearised fit without it; orientations (mrad) when no block
    measures lengths. A fold that leaves a parameter without data gives inf (nothing predicts it)."""
    lin = linearise(problem)
    held = approximate_loo(lin, folds)
    kind = "length" if np.any(lin.data & (lin.kind == "length")) else "angle"
    raw = np.where(np.isnan(held.raw), np.inf, held.raw)
    return norms(lin, raw, kind)


@dataclass
class Criteria:
    rows: int                  # data rows m
    parameters: float          # effective number of parameters p (trace of the hat matrix)
    ssr: float                 # sum of squared scaled data residuals
    aic: float                 # m log(SSR / m) + 2 p
    bic: float                 # m log(SSR / m) + p log m
    fpe: float                 # Akaike's final prediction error, as a factor on the training mean square
    gcv: float                 # generalised cross-validation, the same way

    def to_dict(self) -> dict:
        return dict(vars(self))


def information_criteria(lin: Linearised) -> Criteria:
    """AIC, BIC (noise level estimated from the residuals), FPE = (m + p) / (m - p) and GCV = 1 / (1 - p/m)^2
    (factors on the training mean square)."""
    m = lin.n_data
    p = effective_parameters(lin)
    ssr = float(np.sum(lin.r[lin.data] ** 2))
    base = m * np.log(max(ssr, 1e-300) / m)
    fpe = (m + p) / (m - p) if m > p else float("inf")
    gcv = 1.0 / (1.0 - p / m) ** 2 if m > p else float("inf")
    return Criteria(m, p, ssr, base + 2 * p, base + p * np.log(m), fpe, gcv)


# ---------------------------------------------------------------- evidence
@dataclass
class ModelEvidence:
    log_evidence: float        # log p(y) of the linear Gaussian model, maximised over the noise level
    noise2: float              # its noise variance, in units of the stated sigma^2
    flat_rank: int             # dimensions projected out (flat-prior columns)
    strength: float | None = None    # nominal_evidence: the common prior strength (physical scales) that maximises it
    by_family: dict | None = None    # nominal_evidence: the strength of each scale family, as calibrate's default prior


def log_evidence(J: np.ndarray, y: np.ndarray, prior_sigma: np.ndarray, noise2: float | None = None) -> ModelEvidence:
    """log N(y_perp; 0, s2 I + A S A^T) with y_perp, A the data and the prior columns after projecting out the
    flat columns (prior_sigma inf), S = diag(prior_sigma^2), maximised over s2 unless `noise2` is given.
    The flat columns' improper prior makes the value comparable only between models with the same flat
    columns (the same registration frames) on the same data rows."""
    sig = np.asarray(prior_sigma, float)
    flat = ~np.isfinite(sig)
    rank_flat, (yp, A) = project_out(J[:, flat], np.asarray(y, float), J[:, ~flat] * sig[~flat])
    m_eff = len(yp) - rank_flat
    U, d, _ = np.linalg.svd(A, full_matrices=False) if A.shape[1] else (np.zeros((len(yp), 0)), np.zeros(0), None)
    rank = int(np.sum(d > RANK_TOL * d[0])) if len(d) else 0     # directions the prior lets the data take
    U, d = U[:, :rank], d[:rank]
    z = U.T @ yp
    rest = max(float(yp @ yp - z @ z), 0.0)
    n_rest = m_eff - rank

    def neg2(log_s2: float) -> float:
        s2 = np.exp(log_s2)
        v = s2 + d ** 2
        return float(np.sum(z ** 2 / v) + np.sum(np.log(v)) + rest / s2 + n_rest * log_s2
                     + m_eff * np.log(2 * np.pi))

    if noise2 is None:
        import scipy.optimize   # 0.1-0.15 s: only the study's evidence needs it, not every command's start-up
        guess = np.log(max(float(yp @ yp) / max(m_eff, 1), 1e-300))
        best = scipy.optimize.minimize_scalar(neg2, bounds=(guess - 40.0, guess + 5.0), method="bounded",
                                              options={"xatol": 1e-9})
        noise2 = float(np.exp(best.x))
    return ModelEvidence(-0.5 * neg2(np.log(noise2)), noise2, rank_flat)


def nominal_evidence(problem: Problem, options: CalibrationOptions | None = None,
                     strengths=STRENGTHS) -> ModelEvidence:
    """The evidence of `problem`'s model about its registered nominal: every free robot parameter with the
    physically scaled prior (robocal.estimation.physical_scale) centred on its current value (the nominal, for
    a problem not yet fitted), at the strengths that maximise it, one per scale family as calibrate's default
    prior chooses them (docs/validation.md, "One strength per scale family"); a parameter with its own prior
    keeps that sigma; the registration frames, fitted first with the robot at those values, flat. The
    problem's parameters are left as they were."""
    opt = options or CalibrationOptions()
    scales = physical_scales(problem, opt.determined_length, opt.determined_angle)
    params = problem.params
    start, warm = params.values(), copy.deepcopy(problem.warm_starts)
    try:
        registered = register_nominal(problem, opt)
        for n, v in registered.values.items():
            params[n].value = v
        lin = linearise(problem)
    finally:
        params.set_values(start)
        problem.warm_starts = warm
    J, y = lin.J[lin.data], lin.r[lin.data]
    base = np.array([scales.scale.get(n, np.inf) for n in lin.names])
    given = np.array([params[n].prior_sigma if params[n].prior_sigma is not None else np.nan for n in lin.names])
    best = None
    for lam in strengths:
        ev = log_evidence(J, y, np.where(np.isfinite(given), given, lam * base))
        if best is None or ev.log_evidence > best.log_evidence:
            best = ModelEvidence(ev.log_evidence, ev.noise2, ev.flat_rank, float(lam))
    own = np.isfinite(given)
    families = np.array(["user prior" if o else f for f, o in zip(scales.families(lin.names), own)], dtype=object)
    scaled = own | np.isfinite(base)
    if len(set(families[scaled & ~own])) < 2:
        return best
    # the columns with a user's prior enter at their own sigma, held there ("user prior": a fixed family)
    by_family, _ = family_strengths(evidence_basis(J, y, np.where(own, given, base)), families[scaled],
                                    best.strength, np.asarray(strengths, float), fixed=("user prior",))
    lam = np.array([by_family.get(f, 1.0) for f in families])
    ev = log_evidence(J, y, np.where(own, given, lam * base))
    if ev.log_evidence <= best.log_evidence:        # the common strength is already the best (a tie keeps it)
        return ModelEvidence(best.log_evidence, best.noise2, best.flat_rank, best.strength,
                             {f: best.strength for f in families[scaled & ~own]})
    return ModelEvidence(ev.log_evidence, ev.noise2, ev.flat_rank, best.strength,
                         {f: v for f, v in by_family.items() if f != "user prior"})
