"""The nominal model registered to the data, and the default prior chosen there.

`register_nominal` fits only the frames the config lets float to place the robot in the measurement
(base, measurement set-up such as an unknown marker, measured tool frames: physical_scale.is_registration) with
every robot parameter at nominal. Its residuals are the honest "before" figures: they compare robot models,
not an arbitrary choice of frames. `apply_default_prior` linearises there and, if the data leave some robot
parameter looser than its physical scale, gives every robot parameter without a prior a prior of
strength x physical scale (also the ones the data cannot separate: they become prior-only), the strength
chosen by the evidence (robocal.estimation.regularisation).
The problem's parameters are left as they were found, except for the priors added.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from robocal.estimation.chunked_lstsq import evaluator
from robocal.estimation.problem import Evaluation
from robocal.residuals.prior import prior_rows
from robocal.estimation.identifiability import select_base_parameters
from robocal.estimation.physical_scale import is_registration, measured_frames
from robocal.estimation.regularisation import choose_strength
from robocal.estimation.result import block_statistics
from robocal.estimation.solve import levenberg_marquardt, triangle


@dataclass
class Registered:
    names: list[str]                 # registration parameters fitted
    values: dict[str, float]         # their values after the registration
    before: list                     # BlockStats of the registered nominal model
    message: str = ""
    success: bool = False            # the registration's solver converged
    evaluation: Evaluation | None = None    # at the registered values with every free parameter varying, when
                                            # the registration's passes evaluated all of them (`wide`)


@dataclass
class DefaultPrior:
    mode: str                        # auto | none
    applied: bool
    strength: float | None = None    # prior sigma = strength x physical scale (a given strength, or the best
                                     # common one of the evidence)
    noise_ratio: float | None = None # measured noise / stated sigma (evidence estimate)
    names: list[str] = field(default_factory=list)    # parameters that got the prior (those without one of their own)
    loose: list[str] = field(default_factory=list)    # of the kept ones, those the data alone leave beyond their
                                                      # physical scale at the registered nominal model and the
                                                      # stated sigmas: why it was applied
    reason: str = ""
    method: str = "evidence of the linearised Gaussian model"
    by_family: dict[str, float] = field(default_factory=dict)   # the strength each scale family got

    def to_dict(self) -> dict:
        return {"mode": self.mode, "applied": self.applied, "strength_in_physical_scales": self.strength,
                "strength_by_family": dict(self.by_family),
                "noise_over_stated_sigma": self.noise_ratio, "method": self.method,
                "parameters_given_prior": self.names, "loose_at_registered_nominal": self.loose, "reason": self.reason}

    def describe(self) -> str:
        if self.mode == "none":
            return "Default prior: none (solver.regularisation: none)."
        if not self.applied:
            return f"Default prior: not needed ({self.reason})."
        if self.noise_ratio is None:      # a given strength: no evidence was computed
            return (f"Default prior: given to the {len(self.names)} robot parameters without a prior of their own, "
                    f"{sigma_text(self.strength, self.by_family)} ({self.reason}).")
        return (f"Default prior: given to the {len(self.names)} robot parameters without a prior of their own, "
                f"{sigma_text(self.strength, self.by_family)} (chosen by the {self.method}; measured noise "
                f"{self.noise_ratio:.3g} x stated sigma); {self.reason}.")


def sigma_text(strength: float, by_family: dict[str, float]) -> str:
    """"sigma = 0.5 x physical scale", or one per scale family where they differ (the summary and the report)."""
    if len(set(by_family.values())) <= 1:
        return f"sigma = {strength:.3g} x physical scale"
    return "sigma = " + ", ".join(f"{v:.3g} x physical scale ({f}s)" for f, v in by_family.items())


def data_rows(problem, n_rows: int) -> np.ndarray:
    keep = np.ones(n_rows, bool)
    for b in problem.blocks:
        if b.type_name == "prior":
            keep[b.rows] = False
    return keep


def subset_evaluation(problem, ev: Evaluation, names: list[str], free: list[str] | None = None) -> Evaluation:
    """What evaluating with only `names` free would give, from `ev`, taken at the same values with `free`
    (default: the current free parameters) free: its columns of `names`, its data rows and the prior rows of
    `names` (a prior row is its parameter's own). The residuals do not depend on which parameters are free,
    nor a column on the other columns."""
    params = problem.params
    free = params.free_names if free is None else free
    names, free_set = set(names), set(free)
    cols = [k for k, n in enumerate(free) if n in names]     # the subset's columns come in the same order
    with_prior = [p.name for p in params if p.prior_sigma is not None and (p.vary or p.name in free_set)]
    n_prior = len(with_prior)
    m_data = len(ev.r) - n_prior
    if not any(n in names for n in with_prior):
        rows = slice(0, m_data) if n_prior else slice(None)
        return Evaluation(ev.r[rows], ev.J[rows][:, cols], ev.raw[rows], ev.group[rows])
    kept = [m_data + k for k, n in enumerate(with_prior) if n in names]
    rows = np.concatenate([np.arange(m_data), kept])
    first_prior = sum(res.n_terms for res in problem.residuals)
    group = np.concatenate([ev.group[:m_data], np.arange(first_prior, first_prior + len(kept))])
    return Evaluation(ev.r[rows], ev.J[rows][:, cols], ev.raw[rows], group)


def with_current_priors(problem, ev: Evaluation) -> Evaluation:
    """`ev`, an evaluation at the current values with every free parameter varying, with its prior rows
    replaced by those of the current layout (after priors were added): what evaluating again would give."""
    problem.blocks = problem.layout()
    last = problem.blocks[-1] if problem.blocks else None
    m_data = last.rows.start if last is not None and last.type_name == "prior" else len(ev.r)
    pr, pJ, _ = prior_rows(problem.params)
    first_prior = sum(res.n_terms for res in problem.residuals)
    return Evaluation(np.concatenate([ev.r[:m_data], pr]), np.vstack([ev.J[:m_data], pJ]),
                      np.concatenate([ev.raw[:m_data], pr]),
                      np.concatenate([ev.group[:m_data], np.arange(first_prior, first_prior + len(pr))]))


def evaluate_with_free(problem, evaluate, names: list[str]) -> Evaluation:
    """`evaluate()` at the current values with `names` free as well; the free flags are restored."""
    params = problem.params
    flags = [params[n].vary for n in names]
    try:
        for name in names:
            params[name].vary = True
        return evaluate()
    finally:
        for name, vary in zip(names, flags):
            params[name].vary = vary
        problem.blocks = problem.layout()


def fit_subset(problem, names: list[str], options, last: dict | None = None, start: Evaluation | None = None,
               wide: bool = False):
    """Fit only `names` (the rest held at their values); values stay at the fit, `vary` flags are restored.
    last: if given, receives the solver's last evaluation ('x', 'ev'), so that a caller evaluating at the
    solution with the same free set need not evaluate again. start: the problem's evaluation at the current
    values with every free parameter varying (whole Jacobian), if the caller has it: the solver's first
    evaluation is then taken from it (subset_evaluation) instead of a pass over the samples. wide: every pass
    evaluates all the free parameters' columns (sliced for the solver); last['wide'] then holds the last one."""
    params = problem.params
    free = params.free_names
    fixed_now = [n for n in names if not params[n].vary]
    last = {} if last is None else last
    first = subset_evaluation(problem, start, names) if start is not None and not fixed_now else None
    wide = wide and not fixed_now
    x0 = params.value_array([n for n in free if n in names])
    try:
        for n in free:
            params[n].vary = n in names
        for n in fixed_now:
            params[n].vary = True

        evaluate = evaluator(problem, options.chunk_terms)[0]

        def fun(x):
            if first is not None and np.array_equal(x, x0):
                ev, ev_all = first, start
            else:
                params.set_free_values(x)
                if wide:
                    ev_all = evaluate_with_free(problem, evaluate, free)
                    ev = subset_evaluation(problem, ev_all, names, free)
                else:
                    ev, ev_all = evaluate(), None
            last["x"], last["ev"], last["wide"] = np.array(x), ev, ev_all if wide else None
            return ev.r, ev.J, ev.group

        sol = levenberg_marquardt(fun, params.free_values(), *params.free_bounds(), loss=options.loss,
                                  f_scale=options.f_scale, max_iterations=options.max_iterations,
                                  ftol=options.ftol, xtol=options.xtol, gtol=options.gtol)
        params.set_free_values(sol.x)
    finally:
        for n in fixed_now:
            params[n].vary = False
        for n in free:
            params[n].vary = True
    return sol


def register_nominal(problem, options, evaluation: Evaluation | None = None, wide: bool = False) -> Registered:
    """Fit the registration parameters alone (robot at nominal); the problem's parameters are restored.
    evaluation: the evaluation at the current values with every free parameter varying, if the caller has it
    (fit_subset's start). wide: the passes evaluate every free column (fit_subset), so that the result carries
    the evaluation at the registered values (the default prior's linearisation, the fit's start)."""
    params = problem.params
    free = params.free_names
    measured = measured_frames(problem)
    reg = [n for n in free if is_registration(params[n], measured)]
    start = params.values()                     # every value, tied followers included
    warm = copy.deepcopy(problem.warm_starts)   # closed chains assemble from the last solution: keep the fit's
    last: dict = {}
    try:
        sol = fit_subset(problem, reg, options, last, evaluation, wide) if reg else None
        message = sol.message if sol is not None else "nothing to register"
        for n in free:
            params[n].vary = n in reg      # the "before" layout: no prior rows of the robot parameters
        # the solver's last evaluation, if it was at the solution (same free set, so the same rows)
        at_solution = sol is not None and "x" in last and np.array_equal(last["x"], sol.x)
        before = block_statistics(problem, last["ev"] if at_solution else problem.evaluate(jacobian=False))
        values = {n: params[n].value for n in reg}
    finally:
        for n in free:
            params[n].vary = True
        params.set_values(start)
        problem.warm_starts = warm
        problem.blocks = problem.layout()
    return Registered(reg, values, before, message, sol is not None and sol.success,
                      last.get("wide") if at_solution else None)


def apply_default_prior(problem, registered: Registered, scales, rtol: float,
                        chunk_terms: int | None = None, strength: float | None = None) -> DefaultPrior:
    """Add the evidence-scaled physical prior to the kept robot parameters if the data leave one loose.
    chunk_terms: as CalibrationOptions.chunk_terms (robocal.estimation.chunked_lstsq.evaluator).
    strength: a given strength (physical scales) instead: the prior goes on every robot parameter without one,
    centred on its value, whatever the data determine (the choice was made elsewhere, e.g. by held-out error)."""
    params = problem.params
    free = params.free_names
    candidates = {n for n in free if n in scales.scale and params[n].prior_sigma is None}
    if not candidates:
        return DefaultPrior("auto", False, reason="no robot parameter without a prior")
    if strength is not None:
        if not (np.isfinite(strength) and strength > 0):
            raise ValueError(f"prior strength must be a positive number of physical scales, got {strength}")
        names = [n for n in free if n in candidates]
        for n in names:
            params[n].prior_sigma, params[n].prior_mean = strength * scales.scale[n], params[n].value
        return DefaultPrior("auto", True, float(strength), None, names, [],
                            reason="strength given (chosen by held-out error)", method="given strength",
                            by_family={f: float(strength) for f in dict.fromkeys(scales.families(names))})
    if registered.evaluation is not None:       # the registration's last pass, with every column
        ev = registered.evaluation
    else:
        start = params.values()
        warm = copy.deepcopy(problem.warm_starts)
        try:
            x = params.free_values()
            for k, n in enumerate(free):
                x[k] = registered.values.get(n, x[k])
            params.set_free_values(x)               # followers of the registration frames move with them
            ev = evaluator(problem, chunk_terms)[0]()
        finally:
            params.set_values(start)
            problem.warm_starts = warm
    rows = data_rows(problem, len(ev.r))
    # the data rows enter only through inner products of [J r]'s columns: its triangle T (T^T T = [J r]^T [J r])
    # serves the selection and the evidence in place of the m rows, from one factorisation
    # (fewer rows than columns: the rows themselves, so no zero row of a padded triangle enters the evidence)
    n_rows = int(rows.sum())
    if n_rows > len(free):
        T = triangle(ev.J, ev.r, None, len(free), rows)
        J, r = T[:, :-1], T[:, -1]
    else:
        J, r, n_rows = ev.J[rows], ev.r[rows], None
    sel = select_base_parameters(J, free, rtol)
    kept = [free[j] for j in sel.independent]
    sc = np.array([scales.scale[n] if n in candidates else np.inf for n in kept])
    evd = choose_strength(J[:, sel.independent], r, sc, n_rows=n_rows)
    # looseness is a property of the design: judged at the stated sigmas, not at the measured noise, which
    # a model far from the data (a poor nominal, a wrong model) inflates; the data-only standard errors at
    # the stated sigmas do not depend on the strengths, so the common strength's evidence decides it
    at_stated = evd.stderr / np.sqrt(evd.noise2) if evd.noise2 > 0 else evd.stderr
    loose = [n for n, se in zip(kept, at_stated) if n in candidates and se > 1.0]
    if not loose:
        return DefaultPrior("auto", False, None, float(np.sqrt(evd.noise2)),
                            reason="the data determine every kept robot parameter within its physical scale")
    evd = choose_strength(J[:, sel.independent], r, sc, n_rows=n_rows, families=scales.families(kept))
    noise = float(np.sqrt(evd.noise2))
    # every robot parameter gets it, also those the data cannot separate at all: fixing them at nominal
    # leaves the kept ones to absorb their true errors only to first order, and the fit stalls (docs/validation.md)
    names = [n for n in free if n in candidates]
    families = scales.families(names)
    # a family none of whose parameters the selection kept (all confounded) takes the common strength
    by_family = {f: evd.by_family.get(f, evd.strength) for f in dict.fromkeys(families)}
    for n, f in zip(names, families):
        params[n].prior_sigma, params[n].prior_mean = by_family[f] * scales.scale[n], params[n].value
    return DefaultPrior("auto", True, evd.strength, noise, names, loose, by_family=by_family,
                        reason=f"applied because, at the registered nominal model and the stated sigmas, the data "
                               f"alone leave {len(loose)} of them beyond their physical scale: {', '.join(loose)}")
