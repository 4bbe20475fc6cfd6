"""The selection rule committed before the TIAGo study and rejected by it (docs/validation.md, "The rule" and
"The rule on the shipped TIAGo sessions"): every rung fitted at each prior strength of a grid, the strength with
the lowest held-out figure kept, then the one-standard-error rule over the rungs. `robocal select` does not use
it (robocal.estimation.model_selection: one fit a rung at the prior calibrate chooses); the study's benchmarks
and tests/test_selection_rule.py do.

    rung_by_postures(make_problem)     one session: closed-form leave-one-out by posture at each strength
    rung_by_sessions(make_sessions)    two or more: leave-one-session-out at each strength
    choose_rung(figures)               the one-standard-error rule over the rungs
    leave_one_session_out(sessions)    over a list of per-session problems (robocal select's is
                                       cross_validation's session folds over one problem with sessions)
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.model_criteria import held_out_norms
from robocal.estimation.model_selection import one_standard_error
from robocal.estimation.prediction_errors import BlockErrors, primary_errors
from robocal.estimation.problem import Problem
from robocal.estimation.session_holdout import PER_SESSION, held_out_figure, score_session
from robocal.model.parameters import ParameterSet

STRENGTH_GRID = (0.03, 0.1, 0.3, 1.0, 3.0, None)   # prior sigma in physical scales; None: no prior


@dataclass
class RungFigure:
    rms: float                     # held-out RMS of the error norm (mm, or mrad) at the chosen strength
    stderr: float                  # its standard error over the held-out points (delta method)
    strength: float | None         # the prior strength chosen (None: no prior)
    per_strength: list[tuple[float | None, float, float]]   # (strength, rms, stderr) of every strength tried
    how: str                       # "closed-form leave-one-out by posture" | "leave-one-session-out"


def _options(options: CalibrationOptions, strength: float | None) -> CalibrationOptions:
    return replace(options, regularisation="none" if strength is None else "auto", prior_strength=strength)


def _best(per: list[tuple[float | None, float, float]], how: str) -> RungFigure:
    finite = [t for t in per if np.isfinite(t[1])]
    s, r, e = min(finite, key=lambda t: t[1]) if finite else per[0]
    return RungFigure(r, e, s, per, how)


def rung_by_postures(make_problem: Callable[[], Problem], options: CalibrationOptions | None = None,
                     strengths=STRENGTH_GRID) -> RungFigure:
    """One session: for each prior strength, fit a fresh problem of the rung (`make_problem()`) and take the
    closed-form leave-one-out error of every posture; the strength with the lowest RMS."""
    opt = options or CalibrationOptions()
    per = []
    for strength in strengths:
        problem = make_problem()
        calibrate(problem, _options(opt, strength))
        per.append((strength, *held_out_figure(held_out_norms(problem)[1])))
    return _best(per, "closed-form leave-one-out by posture")


def rung_by_sessions(make_sessions: Callable[[], list[Problem]], options: CalibrationOptions | None = None,
                     strengths=STRENGTH_GRID, per_session=("base.*",),
                     fit: Callable[[list[Problem], CalibrationOptions], object] | None = None) -> RungFigure:
    """Two or more sessions: for each prior strength, leave-one-session-out over fresh problems of the rung, one
    per session (`make_sessions()`), the frames matching `per_session` refitted on the held-out session; `fit`
    (sessions, options) -> fitted ParameterSet, a joint fit, is needed for three sessions or more."""
    opt = options or CalibrationOptions()
    per = []
    for strength in strengths:
        o = _options(opt, strength)
        joint = (lambda sessions: fit(sessions, o)) if fit is not None else None
        errors = leave_one_session_out(make_sessions(), o, per_session, joint)
        per.append((strength, *held_out_figure(session_norms(errors))))
    return _best(per, "leave-one-session-out")


def choose_rung(figures: list[RungFigure | None]) -> tuple[int, int]:
    """(chosen, lowest): the one-standard-error rule over the rungs in ladder order (None: a rung not fitted)."""
    rms = np.array([f.rms if f else np.nan for f in figures])
    se = np.array([f.stderr if f else np.nan for f in figures])
    return one_standard_error(rms, se)


def leave_one_session_out(sessions: list[Problem], options: CalibrationOptions | None = None,
                          per_session: Sequence[str] = PER_SESSION,
                          fit: Callable[[list[Problem]], ParameterSet] | None = None) -> list[dict[str, BlockErrors]]:
    """For each session: the errors there of the robot fitted on the others (score_session: the held-out session's per-session frames refitted there; the robot fitted by `calibrate` when one other session remains, else by `fit`, a joint fit of several sessions with their own frames). The problems'
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



def session_norms(errors: list[dict[str, BlockErrors]]) -> np.ndarray:
    """Every held-out point's error norm (mm; mrad if no block measures lengths), all sessions pooled."""
    return np.concatenate([primary_errors(e)[1] for e in errors])
