"""`robocal select`: cross-validate every rung of a config's model ladder and choose one (docs/validation.md)."""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError
from robocal.estimation.cross_validation import cv_table
from robocal.estimation.model_selection import Selection, ladder, one_standard_error
from robocal.workflows.cv import make_folds
from robocal.workflows.evaluate import setup_for_data


def select_model(config, folds: int | None = None, loo: bool = False, group: str | None = None) -> Selection:
    """Cross-validate every rung of the ladder on the same folds and choose by the one-standard-error rule."""
    base = setup_for_data(config)
    fold_list, label = make_folds(base, folds, loo, group)
    rungs = ladder((base.raw or {}).get("parameters"))
    for rung in rungs:
        try:
            setup = setup_for_data(config, parameters=rung.parameters)
        except InputError as exc:
            rung.skipped = exc.reason
            continue
        rung.n_free = len(setup.problem.params.free_names)
        rung.cv = cv_table(setup.problem, fold_list, setup.options)
    rms = np.array([r.cv.rms if r.cv else np.nan for r in rungs])
    se = np.array([r.cv.stderr if r.cv else np.nan for r in rungs])
    if not np.any(np.isfinite(rms)):
        raise InputError("no model of the ladder could be fitted: " + "; ".join(r.skipped for r in rungs))
    chosen, best = one_standard_error(rms, se)
    return Selection(rungs, chosen, best, label)
