"""Synthetic truth on UR5 with 6D poses: exact recovery, and statistics that match the noise."""
import numpy as np
import pytest
from scipy import stats

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from synthetic_cases import identifiable_names, max_pose_error, ur5_pose_problem

TINY = (1e-12, 1e-12)  # "noise-free": a sigma is still needed to weight the rows


def test_noise_free_full_perturbation_recovered_in_every_identifiable_direction():
    rng = np.random.default_rng(3)
    problem = ur5_pose_problem(rng, 60, TINY)
    truth = perturb(problem.params, rng, 2e-3, np.radians(0.2))   # all 54 parameters, 2 mm / 0.2 deg
    simulate_measurements(problem, truth, rng)
    result = calibrate(problem)
    assert result.success and result.selection.rank == 30
    # Whatever the unidentifiable parameters did, the calibrated model must reproduce the true one.
    robot = problem.robot
    checks = random_configurations(robot, problem.joint_names, 100, rng)
    assert max_pose_error(robot, problem.params, truth, problem.joint_names, "tool0", checks) < 1e-9


def test_noise_free_identifiable_parameters_recovered_exactly():
    rng = np.random.default_rng(4)
    problem = ur5_pose_problem(rng, 60, TINY)
    names = identifiable_names(problem)
    truth = perturb(problem.params, rng, 2e-3, np.radians(0.2), patterns=names)
    simulate_measurements(problem, truth, rng)
    result = calibrate(problem)
    assert result.estimated == names
    err = max(abs(problem.params[n].value - truth[n].value) for n in names)
    assert err < 1e-9


@pytest.mark.slow
def test_noisy_monte_carlo_errors_match_predicted_standard_errors():
    """50 trials, sigma 50 um / 50 urad: errors ~ N(0, predicted covariance), residual RMS/sigma ~ 1."""
    rng = np.random.default_rng(5)
    n_poses = 200                   # 1200 rows: sigma_hat/sigma has a spread of 1/sqrt(2 (m - n)) = 0.021
    template = ur5_pose_problem(rng, n_poses)
    names = identifiable_names(template)
    chi2, ratios, n_par = 0.0, [], len(names)
    trials = 50
    for _ in range(trials):
        problem = ur5_pose_problem(rng, n_poses)
        problem.values = template.values.copy()   # one pose plan, fresh truth and noise per trial
        truth = perturb(problem.params, rng, 2e-3, np.radians(0.2), patterns=names)
        simulate_measurements(problem, truth, rng)
        result = calibrate(problem, CalibrationOptions(scale_covariance=False))
        assert result.estimated == names
        e = np.array([problem.params[n].value - truth[n].value for n in names])
        chi2 += e @ np.linalg.solve(result.covariance, e)
        ratios.append(np.sqrt(np.sum(result.solve.fun ** 2) / result.dof))   # sigma_hat / sigma
    dof = trials * n_par
    # The sum of 50 chi-square(n) statistics is chi-square(50 n): two-sided 99.9 % band.
    assert stats.chi2.ppf(0.0005, dof) < chi2 < stats.chi2.ppf(0.9995, dof)
    ratios = np.array(ratios)
    assert np.all((ratios > 0.9) & (ratios < 1.1))             # > 4 spreads on either side
    # each ratio has a standard deviation of 1/sqrt(2 dof); allow 4 standard deviations of the mean
    assert abs(ratios.mean() - 1.0) < 4 / np.sqrt(2 * result.dof) / np.sqrt(trials)


def test_base_parameter_set_independent_of_row_order_and_repeats():
    rng = np.random.default_rng(6)
    problem = ur5_pose_problem(rng, 40)
    truth = perturb(problem.params, rng)
    simulate_measurements(problem, truth, rng)
    first = calibrate(problem).estimated
    for seed in range(3):
        p2 = ur5_pose_problem(np.random.default_rng(6), 40)
        perm = np.random.default_rng(seed).permutation(40)
        p2.values = problem.values[perm]
        p2.residuals[0].samples = np.arange(40)
        p2.residuals[0].set_measurements(problem.residuals[0].measurements[perm])
        assert calibrate(p2).estimated == first


def test_too_few_measurements_is_an_error():
    from robocal.errors import IdentifiabilityError
    rng = np.random.default_rng(1)
    problem = ur5_pose_problem(rng, 5)   # 30 rows for 54 free parameters
    with pytest.raises(IdentifiabilityError, match="30 measurement rows cannot determine 54"):
        calibrate(problem, source="poses.csv")


def test_tied_truth_is_recovered_with_the_tie():
    from robocal.estimation.identifiability import select_base_parameters
    rng = np.random.default_rng(8)
    problem = ur5_pose_problem(rng, 40, TINY)
    problem.params.tie("wrist_3_joint.offset", "wrist_2_joint.offset")
    names = identifiable_names(problem)
    truth = perturb(problem.params, rng, 2e-3, np.radians(0.2), patterns=names)
    truth.set_free_values(truth.free_values())            # the true follower equals its leader
    simulate_measurements(problem, truth, rng)
    result = calibrate(problem)
    assert result.success and "wrist_3_joint.offset" not in result.estimated
    assert max(abs(problem.params[n].value - truth[n].value) for n in names) < 1e-9
    assert problem.params["wrist_3_joint.offset"].value == problem.params["wrist_2_joint.offset"].value
