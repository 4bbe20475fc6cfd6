"""A fitted model scored on another session, and leave-one-session-out (docs/validation.md, "Choosing a model").

Between sessions some frames are placed anew (the tracker moved: `base.*`); every robot parameter is the
same robot. `score_session` gives a session the fitted robot, refits only those per-session frames there
(every other parameter held) and returns the prediction errors of every block. `leave_one_session_out` does
it for each session in turn, with the robot fitted on the other sessions: by `calibrate` when one other session
remains, or by the caller's `fit` (a joint fit of several sessions with their own frames).
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.prediction_errors import BlockErrors, primary_errors, term_errors
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


def leave_one_session_out(sessions: list[Problem], options: CalibrationOptions | None = None,
                          per_session: Sequence[str] = PER_SESSION,
                          fit: Callable[[list[Problem]], ParameterSet] | None = None) -> list[dict[str, BlockErrors]]:
    """For each session: the errors there of the robot fitted on the others (see module doc). The problems'
    parameter values change (each is fitted or scored); start them from the same values."""
    if len(sessions) < 2:
        raise ValueError("leave-one-session-out needs two or more sessions")
    start = [s.params.values() for s in sessions]
    out = []
    for k, held in enumerate(sessions):
        others = [s for j, s in enumerate(sessions) if j != k]
        for s, v in zip(sessions, start):
            s.params.set_values(v)
        if fit is not None:
            fitted = fit(others)
        elif len(others) == 1:
            calibrate(others[0], options)
            fitted = others[0].params
        else:
            raise ValueError("several sessions to fit jointly: pass fit= (a joint fit with per-session frames)")
        out.append(score_session(fitted, held, per_session, options))
    return out


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


def session_norms(errors: list[dict[str, BlockErrors]]) -> np.ndarray:
    """Every held-out point's error norm (mm; mrad if no block measures lengths), all sessions pooled."""
    return np.concatenate([primary_errors(e)[1] for e in errors])
