"""robocal.estimation.evaluation: statistics, folds, posture groups, scoring on other data and cross-validation."""
from pathlib import Path

import numpy as np
import pytest

from robocal.estimation.calibrate import calibrate
from robocal.estimation.cross_validation import cross_validate, edge_folds, kfold, range_excess, posture_groups
from robocal.estimation.prediction_errors import point_stats, subset_residual, term_errors
from robocal.workflows.evaluate import setup_for_data

HERE = Path(__file__).parents[1] / "examples" / "tiago_mocap"
CONFIG = HERE / "offsets_bl.yaml"
VALIDATION = HERE / "data" / "qualisys_2021-11-26_static_postures.csv"


def test_point_stats_per_axis_norm_and_max_in_mm():
    e = np.array([[3e-3, 4e-3, 0.0], [0.0, 0.0, 0.0]])
    s = point_stats(e)
    assert s.n == 2
    assert s.rmse_norm == pytest.approx(np.sqrt(25 / 2))
    assert s.max_norm == pytest.approx(5.0)
    np.testing.assert_allclose(s.rmse_axes, [np.sqrt(4.5), np.sqrt(8.0), 0.0])
    assert np.isnan(point_stats(np.zeros((0, 3))).rmse_norm)


def test_kfold_partitions_the_samples_and_leave_one_out():
    folds = kfold(10, 3)
    assert sorted(np.concatenate(folds).tolist()) == list(range(10))
    assert [len(f) for f in folds] == [4, 3, 3]
    assert all(len(f) == 1 for f in kfold(5, 5))
    with pytest.raises(ValueError):
        kfold(3, 4)


def test_edge_folds_hold_out_each_joints_range_ends_once():
    # joint 0 spans 0..10 (ends: rows 0 and 4), joint 1 spans 0..1 (low end row 0, already taken; high row 2)
    q = np.array([[0.0, 0.0], [5.0, 0.5], [5.0, 1.0], [9.5, 0.3], [10.0, 0.5], [4.0, 0.5]])
    folds = edge_folds(q, fraction=0.1)
    assert [f.tolist() for f in folds] == [[0], [3, 4], [2]]
    # a constant joint makes no fold; the fraction is checked
    assert [f.tolist() for f in edge_folds(np.c_[q[:, 0], np.ones(6)], 0.1)] == [[0], [3, 4]]
    with pytest.raises(ValueError):
        edge_folds(q, 0.5)


def test_posture_groups_repeated_new_and_out_of_range():
    ref = np.array([[0.0, 0.0], [1.0, 1.0]])
    q = np.array([[0.005, -0.005], [0.5, 0.5], [1.04, 0.0], [1.2, 0.5], [0.0, -0.02]])
    assert posture_groups(ref, q).tolist() == [0, 1, 1, 2, 1]
    np.testing.assert_allclose(range_excess(ref, q), [[0, -0.005], [0, 0], [0.04, 0], [0.2, 0], [0, -0.02]], atol=1e-15)


def test_term_errors_equal_the_fit_residuals_and_score_other_data():
    setup = setup_for_data(CONFIG)
    calibrate(setup.problem, setup.options)
    be = term_errors(setup.problem)["BL"]
    np.testing.assert_allclose(be.raw.reshape(-1), setup.problem.evaluate(jacobian=False).raw, atol=1e-12)
    val = setup_for_data(CONFIG, VALIDATION)
    assert len(val.problem.values) == 62 and len(setup.problem.values) == 37
    scored = term_errors(val.problem, setup.problem.params)["BL"]
    assert scored.points().shape == (62, 1, 3)
    # a model fitted on another day predicts worse than it fits, but stays within the measured scale (cm)
    assert be.point_stats().rmse_norm < scored.point_stats().rmse_norm < 10.0


def test_subset_residual_keeps_only_the_terms_of_the_given_samples():
    res = setup_for_data(CONFIG).problem.residuals[0]
    sub = subset_residual(res, [0, 5, 7])
    assert sub.samples.tolist() == [0, 5, 7]
    np.testing.assert_array_equal(sub.measurements, res.measurements[[0, 5, 7]])
    assert res.n_terms == 37


def test_cross_validation_predicts_each_sample_once_without_changing_the_problem():
    setup = setup_for_data(CONFIG)
    before = setup.problem.params.values()
    cv = cross_validate(setup.problem, kfold(37, 5), setup.options)
    assert setup.problem.params.values() == before
    assert cv.blocks["BL"].samples.tolist() == list(range(37))
    assert len(cv.fold_values) == 5 and all(r == 14 for r in cv.fold_ranks)
    fit = setup_for_data(CONFIG)
    calibrate(fit.problem, fit.options)
    trained = term_errors(fit.problem)["BL"].point_stats().rmse_norm
    held_out = cv.point_stats("BL").rmse_norm
    # held-out error exceeds the fit residual (14 parameters, 111 rows: m/(m-n) ~ 1.14 in variance at least)
    assert held_out > trained * np.sqrt(111 / (111 - 14))
    # fold 0, refitted by hand, predicts its samples exactly as cross_validate says
    manual = setup_for_data(CONFIG)
    keep = np.setdiff1d(np.arange(37), kfold(37, 5)[0])
    manual.problem.residuals[0] = subset_residual(manual.problem.residuals[0], keep)
    calibrate(manual.problem, manual.options)
    ref = term_errors(setup.problem, manual.problem.params)["BL"].raw[kfold(37, 5)[0]]
    np.testing.assert_allclose(cv.blocks["BL"].raw[kfold(37, 5)[0]], ref, atol=1e-7)
