"""`robocal cv`'s closed-form leave-out updates (robocal.estimation.leave_out) against explicit refits: exact on a
linear problem, within what the linearisation predicts on a calibration, and refits where it does not apply."""
import dataclasses
from pathlib import Path

import numpy as np

from robocal.estimation.calibrate import calibrate
from robocal.estimation.cross_validation import cv_table, posture_folds
from robocal.estimation.leave_out import closed_form_refusal, leave_out_table
from robocal.estimation import model_criteria as mc
from robocal.workflows.cv import fold_table, run_cv
from robocal.workflows.evaluate import setup_for_data
from test_model_criteria import _linear_case
from validation_cases import write_case


def test_the_leave_out_step_equals_the_refit_of_a_linear_problem():
    # linear least squares: the Gauss-Newton step from the solution IS the refit, so the training rows'
    # residual r_T + J_T d_G equals the brute-force refit's to rounding
    rng = np.random.default_rng(11)
    lin, X, y, P = _linear_case(rng)
    folds = [np.array([4]), np.array([0, 9, 13])]
    held = mc.approximate_loo(lin, folds, steps=True)
    A_full = np.vstack([X, P])
    theta_hat = np.linalg.lstsq(A_full, np.concatenate([y, np.zeros(len(P))]), rcond=None)[0]
    for fold, step in zip(folds, held.steps):
        out = np.isin(np.arange(len(y)) // 3, fold)
        theta = np.linalg.lstsq(np.vstack([X[~out], P]), np.concatenate([y[~out], np.zeros(len(P))]), rcond=None)[0]
        np.testing.assert_allclose(theta_hat + step, theta, rtol=1e-9, atol=1e-12)


def _fresh(cfg):
    setup = setup_for_data(cfg)
    setup.options.regularisation = "none"      # the refits then minimise the same objective less the fold
    return setup


def test_closed_form_cv_table_matches_refitted_folds_of_a_calibration(tmp_path):
    # UR5, 40 postures, 50 um noise, full geometric model. A refit without a fold moves the parameters by about
    # sigma / sqrt(n_fold) (micrometres, microradians) from the fit on all samples; the terms the linearisation
    # drops are of second order in that move over lever arms under a metre, far below a micrometre (the same
    # bound as test_model_criteria's leave-one-out). So every fold's held-out and train RMS, and the pooled
    # figures, must agree with the refits' within 1 um (0.001 mm), for leave-one-out and for 5 folds.
    cfg, _, values = write_case(tmp_path, np.random.default_rng(12), n=40)
    for k in (40, 5):
        folds = posture_folds(values, k)
        closed = _fresh(cfg)
        table, why = leave_out_table(closed.problem, folds, closed.options)
        assert why == "" and table is not None
        ref = _fresh(cfg)
        brute = cv_table(ref.problem, folds, ref.options)
        assert all(f["status"] == "closed form" for f in table.folds)
        for a, b in zip(table.folds, brute.folds):
            assert a["held_out_samples"] == b["held_out_samples"]
            np.testing.assert_allclose(a["validation_rms_norm"], b["validation_rms_norm"], atol=1e-3)
            np.testing.assert_allclose(a["train_rms_norm"], b["train_rms_norm"], atol=1e-3)
        np.testing.assert_allclose([table.rms, table.train_rms], [brute.rms, brute.train_rms], atol=1e-3)
        np.testing.assert_allclose(table.stderr, brute.stderr, rtol=0.05)
        assert table.rms > table.train_rms                    # held out is worse than the fit itself


def test_cv_uses_the_closed_form_by_default_and_refits_on_request(tmp_path):
    cfg, _, _ = write_case(tmp_path, np.random.default_rng(13), n=30)
    table, label, _ = run_cv(cfg, loo=True)
    assert "closed-form leave-out" in label and table.folds[0]["status"] == "closed form"
    refit, label, _ = run_cv(cfg, loo=True, refits=True)
    assert "refitted (--refits)" in label and refit.folds[0]["status"] == "converged"
    np.testing.assert_allclose(table.rms, refit.rms, rtol=0.02)   # the default prior is chosen per refit


def test_a_robust_loss_is_refitted_from_the_start_values(tmp_path):
    cfg, _, values = write_case(tmp_path, np.random.default_rng(14), n=30)
    setup = setup_for_data(cfg)
    options = dataclasses.replace(setup.options, loss="huber")
    folds = posture_folds(values, 5)
    assert "huber" in closed_form_refusal(setup.problem, folds, options)
    start = setup.problem.params.values()
    table, how = fold_table(setup.problem, folds, options)
    assert how.startswith("refitted (the huber loss") and table.folds[0]["status"] == "converged"
    assert setup.problem.params.values() == start            # refused before any fit: the problem is untouched


def test_a_fold_that_leaves_a_parameter_without_data_has_no_step(tmp_path):
    # only sample 0 sees a parameter: without it the step is undetermined (nan) and the fold is named, which
    # makes leave_out_table refuse and fold_table refit
    cfg, _, values = write_case(tmp_path, np.random.default_rng(15), n=20)
    setup = setup_for_data(cfg)
    calibrate(setup.problem, setup.options)
    lin = mc.linearise(setup.problem)
    lin.J[lin.data & (lin.sample != 0), 0] = 0.0       # only sample 0 sees the first parameter
    held = mc.approximate_loo(lin, posture_folds(values, 20), steps=True)
    assert held.undetermined == [0] and np.all(np.isnan(held.steps[0])) and np.all(np.isfinite(held.steps[1:]))


def test_select_writes_the_chosen_rungs_fit_as_a_fresh_calibration_would(tmp_path):
    # one session: every rung is fitted for its closed-form leave-one-out and run_selected writes the chosen
    # rung's fit (run_calibration(fitted=...)) instead of fitting it again; the folder must be the one a fresh
    # fit of that rung writes, file for file
    from robocal.workflows.calibrate import run_calibration
    from robocal.workflows.config_read import read_config
    from robocal.workflows.select import run_selected, select_model
    cfg, _, _ = write_case(tmp_path, np.random.default_rng(17), n=30)
    config = read_config(cfg)
    selection = select_model(config)
    assert selection.chosen in selection.fits and "no refits" in selection.folds
    run_selected(config, selection, tmp_path / "kept")
    fresh = setup_for_data(config, parameters=selection.rungs[selection.chosen].parameters)
    extra = {"selection.json": (tmp_path / "kept" / "selection.json").read_bytes()}
    run_calibration(fresh, tmp_path / "fresh", extra=extra)
    names = sorted(p.name for p in (tmp_path / "kept").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "fresh").iterdir()) and "result.json" in names
    for name in names:
        assert (tmp_path / "kept" / name).read_bytes() == (tmp_path / "fresh" / name).read_bytes(), name


def test_image_points_closed_form_matches_refitted_folds():
    # the camera example (20 images of a checkerboard, 0.3 px noise per coordinate, ~1000 corners): a refit
    # without a fold of 4 images moves the hand-eye and intrinsics by about the noise over sqrt(800) corners,
    # so the dropped second-order terms are far below 1e-3 px; the refits also re-choose the default prior,
    # which moved a fold's figure by under 1e-3 px on 5 folds of this example. Every corner is a 2D norm (u, v
    # together).
    from pathlib import Path
    example = Path(__file__).parents[1] / "examples" / "camera" / "camera.yaml"
    closed, how, _ = run_cv(example, folds=3)
    refit, _, _ = run_cv(example, folds=3, refits=True)
    assert "closed-form" in how and closed.unit == "px" == refit.unit
    for a, b in zip(closed.folds, refit.folds):
        np.testing.assert_allclose(a["validation_rms_norm"], b["validation_rms_norm"], atol=2e-3)
        np.testing.assert_allclose(a["train_rms_norm"], b["train_rms_norm"], atol=2e-3)
    np.testing.assert_allclose(closed.rms, refit.rms, atol=1e-3)
    assert 0.35 < closed.rms < 0.5          # sqrt(2) x 0.3 px per corner: norms of (u, v), not single rows


def test_select_scores_image_points_by_the_closed_form():
    # robocal select on the camera example stopped with StopIteration (closed_form_cv knew only mm and mrad);
    # the ladder is now scored in px per corner: registration alone is far off (the robot's joint offsets are
    # part of the simulated truth), and a rung that explains the images is near sqrt(2) x 0.3 px
    from pathlib import Path
    from robocal.workflows.select import select_model
    selection = select_model(Path(__file__).parents[1] / "examples" / "camera" / "camera.yaml")
    figures = {r.name: r.cv for r in selection.rungs}
    assert figures["registration"].unit == "px" and figures["registration"].rms > 2.0
    assert 0.35 < figures["joint offsets"].rms < 0.5 and selection.rungs[selection.chosen].name != "registration"


def test_cv_of_a_fit_that_fails_is_refused_unless_allowed(tmp_path, capsys):
    """The demo with a cap of 1 iteration: the fit on all samples does not converge, so `robocal cv` stops
    (exit 3) with the fit's refusal and its fix instead of refitting every fold to the same end; with
    --allow-failed the folds are refitted, each saying it did not converge."""
    import shutil
    from robocal.cli.main import main
    demo = Path(__file__).parents[1] / "robocal" / "io" / "demo"
    for f in ("ur5_calibrate.yaml", "ur5_tracker_poses.csv"):
        shutil.copy(demo / f, tmp_path / f)
    config = tmp_path / "ur5_calibrate.yaml"
    config.write_text(config.read_text() + "solver: {max_iterations: 1}\n")
    assert main(["cv", str(config), "-q"]) == 3
    err = capsys.readouterr().err
    assert "the fit on all samples is not converged" in err and "cap of 1 iteration" in err and "Fix:" in err
    assert main(["cv", str(config), "-q", "--folds", "3", "--allow-failed"]) == 0
    assert "refitted (the fit on all samples is not converged)" in capsys.readouterr().out
