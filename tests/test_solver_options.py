"""Solver options: robust losses against outliers, priors, and the ill-conditioned verdict."""
import numpy as np
import pytest

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from synthetic_cases import identifiable_names, max_pose_error, ur5_pose_problem


def _problem_with_outliers(seed, n_out=4):
    rng = np.random.default_rng(seed)
    problem = ur5_pose_problem(rng, 80)
    truth = perturb(problem.params, rng)
    simulate_measurements(problem, truth, rng)
    m = problem.residuals[0].measurements.copy()
    bad = rng.choice(80, n_out, replace=False)
    m[bad, :3] += rng.choice([-1, 1], (n_out, 3)) * 5e-3       # 5 mm = 100 sigma
    problem.residuals[0].set_measurements(m)
    return problem, truth, bad


@pytest.mark.parametrize("loss", ["huber", "soft_l1"])
def test_robust_loss_resists_outliers_that_spoil_least_squares(loss):
    problem, truth, bad = _problem_with_outliers(11)
    checks = random_configurations(problem.robot, problem.joint_names, 30, np.random.default_rng(0))
    plain = calibrate(problem)
    err_plain = max_pose_error(problem.robot, problem.params, truth, problem.joint_names, "tool0", checks)
    problem2, truth2, _ = _problem_with_outliers(11)
    robust = calibrate(problem2, CalibrationOptions(loss=loss, f_scale=3.0))
    err_robust = max_pose_error(problem2.robot, problem2.params, truth2, problem2.joint_names, "tool0", checks)
    # clean fit: ~50 um * sqrt(30/480) ~ 12 um per axis; the outliers drag least squares far beyond that
    assert err_plain > 2e-4
    assert err_robust < 1e-4
    w = robust.solve.weights.reshape(-1, 6)[:, 0]
    # one weight per pose term: the outliers (100 sigma) are down-weighted, clean terms (about 1 sigma per
    # row) keep a weight near 1 (exactly 1 under Huber; 1/sqrt(1 + 1/9) ~ 0.95 under soft-L1)
    # an outlier term (3 rows at 100 sigma, 3 at 1 sigma) has RMS sqrt(5000) sigma per row: Huber weight
    # sqrt(3 / 70.7) = 0.21 on the rows, 0.04 on the squares
    assert np.all(w[bad] < 0.3) and np.median(w) > 0.9


def test_priors_pull_towards_their_mean_and_make_directions_determinable():
    rng = np.random.default_rng(12)
    problem = ur5_pose_problem(rng, 40)
    truth = perturb(problem.params, rng, patterns=identifiable_names(problem))
    simulate_measurements(problem, truth, rng)
    for p in problem.params:
        p.prior_sigma, p.prior_mean = (1e-9 if p.name == "wrist_3_joint.offset" else 1.0), 0.0
    result = calibrate(problem)
    # with a prior on every parameter nothing is dropped; those the data cannot see are named as prior-only
    assert result.unidentifiable == []
    assert "shoulder_pan_joint.rz" in result.prior_only and "wrist_2_joint.offset" not in result.prior_only
    assert abs(problem.params["wrist_3_joint.offset"].value) < 1e-8          # pinned by its tight prior
    assert any(b.type_name == "prior" for b in result.after)


def test_weak_priors_leave_the_estimate_unchanged():
    rng = np.random.default_rng(13)
    a = ur5_pose_problem(rng, 40)
    truth = perturb(a.params, rng, patterns=identifiable_names(a))
    simulate_measurements(a, truth, rng)
    b = ur5_pose_problem(np.random.default_rng(13), 40)
    b.values, b.residuals[0] = a.values, a.residuals[0]
    for p in b.params:
        if p.name in identifiable_names(a):
            p.prior_sigma = 10.0      # 10 m / 10 rad: carries no information next to 50 um data
    calibrate(a)
    calibrate(b)
    for n in identifiable_names(a):
        assert abs(a.params[n].value - b.params[n].value) < 1e-8


def test_ill_conditioned_fit_is_not_reported_as_success():
    rng = np.random.default_rng(14)
    problem = ur5_pose_problem(rng, 40)
    simulate_measurements(problem, perturb(problem.params, rng), rng)
    result = calibrate(problem, CalibrationOptions(condition_limit=1.5))
    assert result.ill_conditioned and not result.success and result.status == "ill-conditioned"
    assert any("ill-conditioned" in s for s in result.identifiability_statements())


def test_result_json_is_strict_even_with_infinite_condition():
    import json
    rng = np.random.default_rng(15)
    problem = ur5_pose_problem(rng, 40)
    simulate_measurements(problem, perturb(problem.params, rng), rng)
    result = calibrate(problem)
    result.condition = float("inf")
    doc = json.loads(result.to_json())          # json.loads rejects nothing, so check the text too
    assert doc["condition_number"] is None and "Infinity" not in result.to_json()
