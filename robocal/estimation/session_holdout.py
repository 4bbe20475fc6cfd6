"""A fitted model scored on another session, and the RMS of held-out errors (docs/validation.md, "Choosing a model").

Between sessions some frames are placed anew (the tracker moved: `base.*`); every robot parameter is the
same robot. `score_session` gives a session the fitted robot, refits only those per-session frames there
(every other parameter held) and returns the prediction errors of every block. `held_out_figure` is the RMS of
held-out error norms with its standard error. Leave-one-session-out over one problem with sessions is
robocal.estimation.cross_validation's (session folds); the study's form over a list of per-session problems
lives with the study (benchmarks/strength_rule.py).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from robocal.estimation.calibrate import CalibrationOptions
from robocal.estimation.prediction_errors import BlockErrors, term_errors
from robocal.estimation.problem import Problem
from robocal.estimation.registration import fit_subset
from robocal.model.parameters import ParameterSet

PER_SESSION = ("base.*",)      # frames placed anew in every session, unless the caller says otherwise


def per_session_names(params: ParameterSet, patterns: Sequence[str] = PER_SESSION) -> list[str]:
    """The parameters matching `patterns` (each must match one)."""
    return list(dict.fromkeys(n for pat in patterns for n in params.select(pat)))


def score_session(fitted: ParameterSet, problem: Problem, per_session: Sequence[str] = PER_SESSION,
                  options: CalibrationOptions | None = None) -> dict[str, BlockErrors]:
    """Prediction errors on `problem` (another session) of the `fitted` parameters, its per-session frames
    refitted there first with every other parameter held. `problem`'s parameters end at those values."""
    params = problem.params
    for p in params:
        if p.name in fitted:
            p.value = fitted[p.name].value
    names = per_session_names(params, per_session)
    if names:
        fit_subset(problem, names, options or CalibrationOptions())
    return term_errors(problem)


def held_out_figure(norms: np.ndarray) -> tuple[float, float]:
    """(RMS, its standard error) of held-out error norms, the standard error by the delta method on the mean
    square over the points (d sqrt(x) = dx / (2 sqrt(x))). NaN norms are left out; an infinite one (a point
    nothing predicts) makes the RMS infinite."""
    v = np.asarray(norms, float)
    v = v[~np.isnan(v)]
    if not len(v):
        return float("nan"), float("nan")
    if not np.all(np.isfinite(v)):
        return float("inf"), float("inf")
    ms = float(np.mean(v ** 2))
    se = float(np.std(v ** 2, ddof=1) / np.sqrt(len(v))) if len(v) > 1 else float("nan")
    return float(np.sqrt(ms)), se / (2 * np.sqrt(ms)) if ms > 0 else float("nan")
