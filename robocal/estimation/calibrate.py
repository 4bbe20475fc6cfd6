"""Calibration: identifiability at the start point, the solve, and the statistics of the result.

Flow: register the nominal model (fit only the frames the config lets float: base, measurement set-up,
tool) for the "before" figures and as the point where the default prior's strength is chosen
(robocal.estimation.regularisation); evaluate the Jacobian at the initial parameters on the actual
samples; keep a deterministic set of base parameters (the rest are fixed at their initial values and reported with what they are
confounded with); solve; compute the covariance sigma^2 (J^T J)^-1 with sigma^2 = SSR / (m - n)
(or 1 when the stated sigmas are trusted: scale_covariance=False); classify what the data determine
(robocal.estimation.determinacy) and refuse an implausible fit (robocal.estimation.plausibility).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable

import numpy as np

from robocal.errors import IdentifiabilityError, InputError
from robocal.estimation.chunked_lstsq import evaluator
from robocal.estimation.determinacy import classify
from robocal.estimation.identifiability import covariance, select_base_parameters
from robocal.estimation.physical_scale import (DETERMINED_ANGLE, DETERMINED_LENGTH,
                                               physical_scales)
from robocal.estimation.findings import find
from robocal.estimation.plausibility import check_fit, nominal_values
from robocal.estimation.registration import (DefaultPrior, apply_default_prior, data_rows, register_nominal,
                                             evaluate_with_free, subset_evaluation, with_current_priors)
from robocal.estimation.problem import Evaluation, Problem
from robocal.estimation.session_figures import session_figures
from robocal.estimation.result import BlockStats, CalibrationResult, block_statistics
from robocal.estimation.solve import Iteration, levenberg_marquardt, r_factor, triangle

log = logging.getLogger(__name__)
MAX_SELECTION_PASSES = 3
WIDE_REGISTRATION = 1_000_000   # Jacobian entries (rows x requested parameters) up to which the registration's
                                # passes evaluate every column (fit_subset's wide)


@dataclass
class CalibrationOptions:
    loss: str = "linear"             # linear | huber | soft_l1 (per measurement term)
    f_scale: float = 3.0             # robust-loss knee, in units of sigma
    max_iterations: int = 100
    rank_rtol: float = 1e-8          # remaining-norm threshold of the base-parameter selection
    condition_limit: float = 1e8     # above this the fit is reported as ill-conditioned
    scale_covariance: bool = True    # sigma^2 from the residuals (True) or the stated sigmas (False)
    ftol: float = 1e-12
    xtol: float = 1e-12
    gtol: float = 1e-10
    regularisation: str = "auto"     # auto: a physically scaled prior where the data leave a direction loose | none
    prior_strength: float | None = None   # auto with a given strength (physical scales, e.g. chosen by held-out
                                     # error: robocal.estimation.model_selection); None: the evidence chooses it
    determined_length: float = DETERMINED_LENGTH   # m: standard error below which a length is determined
    determined_angle: float = DETERMINED_ANGLE     # rad: the same for an angle
    register_before: bool = True     # "before" figures after registering the nominal model (else: as given)
    chunk_terms: int | None = None   # terms a chunk when the Jacobian is kept as its triangle (None: automatic
                                     # above chunked_lstsq.LARGE_JACOBIAN entries; 0: never)


def calibrate(problem: Problem, options: CalibrationOptions | None = None,
              progress: Callable[[Iteration], None] | None = None, source: str = "data") -> CalibrationResult:
    """Fit the free parameters of `problem` (in place) and return the result with statistics."""
    opt = options or CalibrationOptions()
    if opt.regularisation not in ("auto", "none"):
        raise InputError(f"regularisation must be auto or none, got '{opt.regularisation}'",
                         field="solver.regularisation")
    params = problem.params
    nominal = nominal_values(params)
    scales = physical_scales(problem, opt.determined_length, opt.determined_angle)
    requested = params.free_names
    # one evaluation at the start serves the checks, the registration's first step and (unless the default
    # prior changes the rows) the selection and the fit's first step: all at the same values
    evaluate, chunked = evaluator(problem, opt.chunk_terms)   # chunked: J is only ever its triangle
    # (in chunks, a default prior's rows cannot be added to the triangles: there the check costs residuals only)
    start_ev = problem.evaluate(jacobian=False) if chunked and opt.regularisation == "auto" else evaluate()
    m = len(start_ev.r)
    if m < len(requested):
        raise IdentifiabilityError(
            f"{source}: {m} measurement rows cannot determine {len(requested)} free parameters; add samples or "
            f"fix parameters")
    if not np.all(np.isfinite(start_ev.r)):
        raise IdentifiabilityError(f"{source}: the residuals are not finite at the initial parameters")
    # a small problem's registration evaluates every column (cheap next to a pass's fixed cost): its last pass
    # then serves the default prior's linearisation at the registered frames
    wide = opt.regularisation == "auto" and not chunked and m * len(requested) <= WIDE_REGISTRATION
    registered = (register_nominal(problem, opt, None if chunked else start_ev, wide)
                  if opt.register_before or opt.regularisation == "auto" else None)
    default_prior = (apply_default_prior(problem, registered, scales, opt.rank_rtol, opt.chunk_terms,
                                         opt.prior_strength)
                     if opt.regularisation == "auto" else DefaultPrior("none", False))
    evaluate, was_chunked = evaluator(problem, opt.chunk_terms)[0], chunked
    chunked = evaluator(problem, opt.chunk_terms)[1]
    if chunked != was_chunked or start_ev.J is None or (chunked and default_prior.applied):
        ev0 = evaluate()               # the layout of the full free set, with any prior
    else:
        ev0 = with_current_priors(problem, start_ev) if default_prior.applied else start_ev
        problem.blocks = problem.layout()
    m = len(ev0.r)
    before = registered.before if registered is not None and opt.register_before else block_statistics(problem, ev0)

    last = {}
    wide_passes: list = []   # (x, evaluation with every requested parameter free) of the last passes, when `widen`

    def fun(x):
        if "x" in last and last["x"].shape == np.shape(x) and np.array_equal(last["x"], x):
            ev = last["ev"]
            return ev.r, ev.J, ev.group
        params.set_free_values(x)
        if widen:
            ev_all = evaluate_with_free(problem, evaluate, requested)
            ev = subset_evaluation(problem, ev_all, params.free_names, requested)
            wide_passes[:] = wide_passes[-2:] + [(np.array(x), ev_all)]
        else:
            ev = evaluate()
        last["x"], last["ev"] = np.array(x), ev
        return ev.r, ev.J, ev.group

    # The selection is made at the start point. A degenerate start (an unknown marker guessed on a joint
    # axis) can hide a parameter completely; such parameters, and only those, are examined again at the
    # solution, and the fit repeated with the ones the data now determine. Structural dependencies
    # decided at the start stay decided, so the same data always give the same set.
    # Identifiability is a property of the data: prior rows are left out of the selection, and parameters
    # with a prior are then kept whatever the data say (their prior determines them).
    start_rows = data_rows(problem, m)
    with_prior = [j for j, n in enumerate(requested) if params[n].prior_sigma is not None]
    # one factorisation of [J r] at the start serves the selection (its R block) and the first step
    start = triangle(ev0.J, ev0.r, None, len(requested), start_rows)
    first = select_base_parameters(start[:len(requested), :len(requested)], requested, opt.rank_rtol)
    prior_only = [requested[j] for j in first.dependent if j in with_prior]     # kept only by their prior
    selection = _apply_selection(params, requested, None, opt.rank_rtol, first.keep_also(with_prior))
    kept = [requested.index(n) for n in params.free_names]
    first_triangle = None
    if not chunked:                    # the solver starts where ev0 was taken
        last["x"], last["ev"] = params.free_values(), Evaluation(ev0.r, ev0.J[:, kept], ev0.raw, ev0.group)
        first_triangle = columns_triangle(start, kept, ev0, start_rows)
        wide_passes.append((last["x"], ev0))
    for _attempt in range(MAX_SELECTION_PASSES):
        # parameters without effect at the start are examined again at the solution: the solver's passes then
        # evaluate every requested column (a wider GEMM), so its last one serves that check too
        widen = bool(selection.no_effect) and not chunked and _attempt < MAX_SELECTION_PASSES - 1
        log.info("calibrating %d of %d requested parameters from %d rows", selection.rank, len(requested), m)
        lo, hi = params.free_bounds()
        sol = levenberg_marquardt(fun, params.free_values(), lo, hi, loss=opt.loss, f_scale=opt.f_scale,
                                  max_iterations=opt.max_iterations, ftol=opt.ftol, xtol=opt.xtol, gtol=opt.gtol,
                                  callback=progress, first_triangle=first_triangle if _attempt == 0 else None)
        params.set_free_values(sol.x)
        hidden = selection.no_effect
        if not hidden or _attempt == MAX_SELECTION_PASSES - 1:
            break
        for name in requested:
            params[name].vary = True
        allowed = set(selection.independent) | set(hidden)
        ev_all = next((e for xw, e in wide_passes if xw.shape == sol.x.shape and np.array_equal(xw, sol.x)), None)
        ev_all = ev_all if ev_all is not None else evaluate()
        wide_passes.clear()
        again_data = select_base_parameters(triangle(ev_all.J, ev_all.r, None, len(requested), start_rows)[:-1, :-1],
                                            requested, opt.rank_rtol, allowed)
        prior_only = [requested[j] for j in again_data.dependent if j in with_prior]
        again = again_data.keep_also(with_prior)
        if again.independent == selection.independent:   # same set; explain it as seen at the solution
            selection = _apply_selection(params, requested, None, opt.rank_rtol, again)
            break
        log.info("%d parameters without effect at the start are determined at the solution: solving again",
                 again.rank - selection.rank)
        selection = _apply_selection(params, requested, None, opt.rank_rtol, again)
    x = params.free_values()
    reuse = "x" in last and last["x"].shape == x.shape and np.array_equal(last["x"], x)
    ev = last["ev"] if reuse else evaluate()   # the solver's last evaluation is at the solution
    after = block_statistics(problem, ev)
    n = len(sol.x)
    dof = m - n
    w = sol.weights
    ssr = float(np.sum((ev.r * (w if w is not None else 1.0)) ** 2))
    sigma2 = (ssr / dof if dof > 0 else float("nan")) if opt.scale_covariance else 1.0
    # the solver's last QR, of [Jw r] at its solution, has the same column geometry as Jw (R^T R = Jw^T Jw)
    Rw = (sol.triangle if sol.triangle is not None else triangle(ev.J, ev.r, w, n))[:n, :n]
    final_sel = select_base_parameters(Rw, params.free_names, opt.rank_rtol)
    cov = covariance(Rw, sigma2) if final_sel.rank == n else np.full((n, n), np.nan)
    for name, s in zip(params.free_names, np.sqrt(np.abs(np.diag(cov)))):
        params[name].stderr = float(s)
    ill = final_sel.condition > opt.condition_limit or final_sel.rank < n
    result = CalibrationResult(
        params=params, requested=requested, selection=selection, covariance=cov, before=before, after=after,
        solve=sol, dof=dof, sigma2=sigma2, condition=final_sel.condition, ill_conditioned=ill,
        condition_limit=opt.condition_limit, n_rows=m, prior_only=prior_only,
        determined_thresholds=(opt.determined_length, opt.determined_angle))
    result.weakest_direction = weakest_direction(Rw, params.free_names) if ill else []
    result.sessions = session_figures(problem)
    free = params.free_names
    data_rows_now = data_rows(problem, len(ev.r))
    # the data rows' column geometry: the solver's triangle when every row is data, else factored here; the
    # rows themselves when fewer than the columns (classify then knows which directions no row sees)
    if data_rows_now.sum() < n:
        J_data = (ev.J * (w[:, None] if w is not None else 1.0))[data_rows_now]
    else:
        J_data = Rw if data_rows_now.all() else triangle(ev.J, ev.r, w, n, data_rows_now)[:n, :n]
    noise2 = sigma2 if np.isfinite(sigma2) else 1.0
    with_prior = {p.name for p in params if p.prior_sigma is not None}
    # what the data alone say: the parameters they can identify, the ones set by the prior held at their values
    set_by_prior = set(prior_only)
    data_names = [name for name in free if name not in set_by_prior]
    cols = [free.index(name) for name in data_names]
    result.determinacy = classify(data_names, J_data[:, cols], noise2, scales.threshold(data_names),
                                  scales.of(data_names), [name for name in free if name in set_by_prior],
                                  [requested[j] for j in selection.dependent], with_prior)
    for name in free:
        params[name].stderr_data = result.determinacy.stderr[name]
    result.default_prior = default_prior
    result.registration = registered.names if registered is not None else []
    result.registration_values = dict(registered.values) if registered is not None else {}
    result.robot_size = scales.size
    result.scales = scales
    result.refusals = check_fit(result, nominal, scales, opt.regularisation, opt.max_iterations)
    # a finding needs a converged, well-conditioned fit (a parameter refusal elsewhere does not hide one)
    result.findings = (find(params, nominal, scales, result.determinacy.stderr)
                       if sol.success and not ill else [])
    return result


def weakest_direction(R: np.ndarray, names: list[str]) -> list[str]:
    """The parameters taking part in the weakest direction of the column-scaled R (an ill-conditioned fit)."""
    norms = np.linalg.norm(R, axis=0)
    _, _, Vt = np.linalg.svd(R / np.where(norms > 0, norms, 1.0), full_matrices=False)
    v = np.abs(Vt[-1])
    return [n for n, c in zip(names, v) if c > 0.1 * v.max()]


def columns_triangle(T: np.ndarray, kept: list[int], ev: Evaluation, data_rows: np.ndarray) -> np.ndarray:
    """Triangle of [J[:, kept] r] over all rows of `ev`, from T, the triangle of [J r] over its data rows:
    T's columns have the same inner products as [J r]'s (T^T T = [J r]^T [J r]), so factoring the kept ones
    with the other rows (the priors) stacked below gives it without touching the m data rows again."""
    cols = list(kept) + [T.shape[1] - 1]
    others = np.flatnonzero(~data_rows)
    block = np.vstack([T[:, cols], np.column_stack([ev.J[others][:, kept], ev.r[others]])])
    return r_factor(block, overwrite=True)


def _apply_selection(params, requested, J, rtol, selection=None):
    """Fix the parameters the data cannot determine (recording why); free the rest."""
    selection = selection or select_base_parameters(J, requested, rtol)
    for name in requested:
        p = params[name]
        p.vary, p.identifiable, p.confounded_with, p.stderr, p.stderr_data = True, True, [], None, None
    for j in selection.dependent:
        p = params[requested[j]]
        p.vary, p.identifiable = False, False
        p.confounded_with = selection.confounded_with(j)
    return selection


__all__ = ["calibrate", "CalibrationOptions", "CalibrationResult", "BlockStats"]
