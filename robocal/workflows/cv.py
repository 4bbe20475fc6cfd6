"""`robocal cv`: cross-validate a config on folds of its samples (K-fold, leave-one-out, leave-one-group-out)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from robocal.errors import InputError
from robocal.estimation.cross_validation import CVTable, cv_table, posture_folds, session_folds
from robocal.estimation.leave_out import leave_out_table
from robocal.estimation.problem import Problem
from robocal.workflows.input_checks import check_inputs
from robocal.workflows.setup import load_config


def run_cv(config: str | Path, folds: int | None = None, loo: bool = False, group: str | None = None,
           allow_failed: bool = False, refits: bool = False) -> tuple[CVTable, str, list[str]]:
    """(the CV table, how the folds were made, notes) of a config; its data pass the units check first. The
    folds are the closed-form leave-out updates of the fit on all samples where its linearisation allows it
    (robocal.estimation.leave_out), else (or with `refits`) each fold is refitted. A fit on all samples that
    fails raises FitFailed (robocal.estimation.leave_out) unless allow_failed (then the folds are refitted)."""
    setup = load_config(config)
    notes = check_inputs(setup, allow_failed)
    fold_list, label = make_folds(setup, folds, loo, group)
    table, how = fold_table(setup.problem, fold_list, setup.options, refits, allow_failed)
    return table, f"{label}, {how}", notes


def fold_table(problem, folds: list[np.ndarray], options, refits: bool = False,
               allow_failed: bool = True) -> tuple[CVTable, str]:
    """(CV table, how its folds were scored): the closed-form leave-out of the fit on all samples, or refits
    when asked for or when the linearised fit does not allow it (the reason in the description). `problem` may
    end fitted. Without allow_failed, a fit on all samples that does not converge (or is ill-conditioned)
    raises robocal.estimation.leave_out.FitFailed: its folds would be refitted as long, to the same end."""
    why = "refitted (--refits)"
    if not refits:
        start = problem.params.copy()
        table, reason = leave_out_table(problem, folds, options, refuse_failed=not allow_failed)
        if table is not None:
            return table, "closed-form leave-out of the fit on all samples (no refits)"
        why = f"refitted ({reason})"
        problem = Problem(problem.robot, start, problem.joint_names, problem.values, problem.residuals,
                          problem.directions, problem.sessions)
    return cv_table(problem, folds, options), why


def group_folds(setup, column: str) -> list[np.ndarray]:
    """Leave-one-group-out folds: the samples sharing a value of `column` of the data CSV, in order of first
    appearance. A sample's group is read from the row it came from."""
    labels = []
    for file, row in setup.sample_rows:
        tab = setup.tables[file]
        if not tab.has(column):
            raise InputError(f"no group column '{column}' (columns present: {', '.join(tab.header)})",
                             source=str(tab.path), field=column)
        labels.append(tab.cells[row][tab.header.index(column)].strip())
    groups = list(dict.fromkeys(labels))
    if len(groups) < 2:
        raise InputError(f"column '{column}' holds a single group: nothing to hold out", field=column)
    labels = np.array(labels)
    return [np.flatnonzero(labels == g) for g in groups]


def make_folds(setup, folds: int | None = None, loo: bool = False, group: str | None = None):
    """(folds, description) of a config's samples (docs/validation.md, "Folds"):
    `group` column -> leave-one-group-out; two or more sessions -> leave-one-session-out (unless K folds or
    leave-one-out are asked for); `loo` -> leave-one-posture-out; else K folds of whole postures (default 5):
    repeated postures are held out together, so a repeat in training never predicts its twin."""
    problem = setup.problem
    n = len(problem.values)
    if group:
        return group_folds(setup, group), f"leave-one-group-out on column '{group}'"
    sessions = problem.sessions
    if sessions is not None and not loo and folds is None:
        return session_folds(sessions), f"leave-one-session-out ({len(sessions.names)} sessions)"
    k = n if loo else folds or 5
    if not loo and not 2 <= k <= n:
        raise InputError(f"need 2 <= folds <= {n} samples, got {k}", field="--folds")
    try:
        out = posture_folds(problem.values, k)
    except ValueError as exc:
        raise InputError(str(exc), source=setup.source, field="data") from None
    return out, (f"leave-one-posture-out ({len(out)} postures)" if loo else f"{len(out)}-fold by posture")
