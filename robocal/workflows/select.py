"""`robocal select`: cross-validate every rung of a config's model ladder, choose one, and calibrate the
chosen model on all samples into an output folder, as `robocal calibrate` would (docs/validation.md)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from robocal.errors import InputError
from robocal.estimation.calibrate import calibrate
from robocal.estimation.cross_validation import posture_folds
from robocal.estimation.model_selection import Selection, closed_form_cv, ladder, one_standard_error
from robocal.workflows.calibrate import CalibrationRun, run_calibration
from robocal.workflows.input_checks import check_inputs
from robocal.workflows.config_read import read_config, with_parameters
from robocal.workflows.config_types import CalibrationConfig
from robocal.workflows.cv import fold_table, make_folds
from robocal.workflows.setup import build_setup


def select_model(config, folds: int | None = None, loo: bool = False, group: str | None = None,
                 allow_failed: bool = False, refits: bool = False) -> Selection:
    """Score every rung of the ladder on held-out data and choose by the one-standard-error rule
    (docs/validation.md, "Choosing a model"): with two or more sessions, leave-one-session-out; with one, the
    closed-form leave-one-out by posture of each rung's fit (no refits); `folds`, `loo` or `group` ask for
    those folds, scored as `robocal cv` scores them (workflows.cv.fold_table: the closed-form leave-out where
    the linearised fit allows it, else or with `refits` refitted). The data pass the input checks first (notes
    go into the selection's notes). `config`: a YAML path or a CalibrationConfig (read once by the caller).
    With the closed form, each rung keeps its fitted setup (`Selection.fits`): run_selected writes the chosen
    one without fitting it again."""
    config = config if isinstance(config, CalibrationConfig) else read_config(config)
    camera_cache: dict = {}                # every rung sees the same images: a camera's PnP solved once each
    base = build_setup(config, camera_cache=camera_cache)
    notes = check_inputs(base, allow_failed)
    closed_form = base.problem.sessions is None and folds is None and not loo and not group and not refits
    if closed_form:
        n = len(base.problem.values)
        fold_list = posture_folds(base.problem.values, n)
        label = f"closed-form leave-one-out by posture ({len(fold_list)} postures, no refits)"
    else:
        fold_list, label = make_folds(base, folds, loo, group)
    rungs = ladder(config.parameters.to_dict())
    fits, hows = {}, []
    spare = base                           # the config's own set-up serves the rung that is the config
    for k, rung in enumerate(rungs):
        try:
            rung_config = with_parameters(config, rung.parameters)
            if spare is not None and rung_config == config:
                setup, spare = spare, None     # not built twice
            else:
                setup = build_setup(rung_config, camera_cache=camera_cache)
        except InputError as exc:
            rung.skipped = exc.reason
            continue
        rung.n_free = len(setup.problem.params.free_names)
        if closed_form:
            nominal = setup.problem.params.copy()
            result = calibrate(setup.problem, setup.options, source=config.source)
            fits[k] = (setup, nominal, result)
            rung.cv = closed_form_cv(setup.problem, fold_list)
        else:
            rung.cv, how = fold_table(setup.problem, fold_list, setup.options, refits)
            hows.append((rung.name, how))
    rms = np.array([r.cv.rms if r.cv else np.nan for r in rungs])
    se = np.array([r.cv.stderr if r.cv else np.nan for r in rungs])
    if not np.any(np.isfinite(rms)):
        raise InputError("no model of the ladder could be fitted: " + "; ".join(r.skipped for r in rungs))
    chosen, best = one_standard_error(rms, se)
    if len({h for _, h in hows}) == 1:
        label += ", " + hows[0][1]
    elif hows:                        # a rung the closed form does not allow was refitted
        label += ", " + "; ".join(f"{name}: {h}" for name, h in hows)
    return Selection(rungs, chosen, best, label, notes=notes, fits=fits, camera_cache=camera_cache)


def run_selected(config, selection: Selection, output_dir: str | Path | None = None, *, force: bool = False,
                 allow_failed: bool = False) -> CalibrationRun:
    """Calibrate the chosen rung on all samples and write its folder, with selection.json beside (the chosen
    rung's fit from the selection when it kept one: the same setup and options, so the same fit)."""
    extra = {"selection.json": (json.dumps(selection.to_dict(), indent=2, allow_nan=True) + "\n").encode()}
    kept = selection.fits.get(selection.chosen)
    if kept is not None:
        setup, nominal, result = kept
        return run_calibration(setup, output_dir, force=force, allow_failed=allow_failed, extra=extra,
                               fitted=(nominal, result))
    config = config if isinstance(config, CalibrationConfig) else read_config(config)
    setup = build_setup(with_parameters(config, selection.rungs[selection.chosen].parameters),
                        camera_cache=selection.camera_cache)
    return run_calibration(setup, output_dir, force=force, allow_failed=allow_failed, extra=extra,
                           source=str(config.source))
