"""Synthetic truth on Panda: marker points only, and a mix of contact residuals with unknown set-ups."""
import numpy as np
import pytest
from scipy import stats

from robocal import load_example
from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.residuals import BallBarResidual, PlaneResidual, RigidPointsResidual, SphereResidual
from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from synthetic_cases import identifiable_names

ARM = [f"panda_joint{i}" for i in range(1, 8)]
MARKERS = [[0.05, 0.0, 0.02], [-0.03, 0.04, 0.05], [0.0, -0.05, 0.08]]


def marker_problem(rng, n, sigma, values=None):
    robot = load_example("panda")
    params = robot_parameters(robot, ARM, "full", base=True)
    values = random_configurations(robot, ARM, n, rng) if values is None else values
    res = RigidPointsResidual("mocap", "panda_hand", np.arange(n), np.zeros((n, 9)), MARKERS, sigma=sigma)
    return Problem(robot, params, ARM, values, [res])


def test_markers_noise_free_recovery():
    rng = np.random.default_rng(21)
    problem = marker_problem(rng, 50, 1e-12)
    names = identifiable_names(problem)
    truth = perturb(problem.params, rng, 2e-3, np.radians(0.2), patterns=names)
    simulate_measurements(problem, truth, rng)
    result = calibrate(problem)
    assert result.success and result.estimated == names
    assert max(abs(problem.params[n].value - truth[n].value) for n in names) < 1e-9


@pytest.mark.slow
def test_markers_noisy_monte_carlo_consistent_with_standard_errors():
    rng = np.random.default_rng(22)
    sigma = 1e-4
    n_poses = 120                   # 1080 rows: RMS/sigma has a spread of 1/sqrt(2 (m - n)) = 0.022
    template = marker_problem(rng, n_poses, sigma)
    names = identifiable_names(template)
    trials, chi2, ratios = 50, 0.0, []
    for _ in range(trials):
        problem = marker_problem(rng, n_poses, sigma, template.values)
        truth = perturb(problem.params, rng, 2e-3, np.radians(0.2), patterns=names)
        simulate_measurements(problem, truth, rng)
        result = calibrate(problem, CalibrationOptions(scale_covariance=False))
        e = np.array([problem.params[n].value - truth[n].value for n in names])
        chi2 += e @ np.linalg.solve(result.covariance, e)
        ratios.append(np.sqrt(np.sum(result.solve.fun ** 2) / result.dof))   # sigma_hat / sigma
    dof = trials * len(names)
    assert stats.chi2.ppf(0.0005, dof) < chi2 < stats.chi2.ppf(0.9995, dof)
    ratios = np.array(ratios)
    assert np.all((ratios > 0.9) & (ratios < 1.1))             # > 4 spreads on either side
    assert abs(ratios.mean() - 1.0) < 4 / np.sqrt(2 * result.dof) / np.sqrt(trials)


def contact_problem(rng, sigma, n_plane=40, n_sphere=40, n_bar=60):
    robot = load_example("panda")
    params = robot_parameters(robot, ARM, "full")
    tip = (0.02, 0.01, 0.15)   # off the joint-7 axis, as a real probe is
    n = n_plane + n_sphere + n_bar
    values = random_configurations(robot, ARM, n, rng, span=0.7)
    s = np.arange(n)
    blocks = [
        PlaneResidual("table", "panda_hand", s[:n_plane], normal=(0.05, -0.02, 1.0), offset=0.25, point=tip,
                      tip_radius=0.003, sigma=sigma),
        SphereResidual("ball", "panda_hand", s[n_plane:n_plane + n_sphere], centre=(0.45, 0.1, 0.35), radius=0.0125,
                       point=tip, tip_radius=0.003, sigma=sigma),
        BallBarResidual("bar", "panda_hand", s[n_plane + n_sphere:], np.zeros(n_bar), centre=(0.3, -0.2, 0.2),
                        offset=0.25, point=tip, sigma=sigma),
    ]
    return Problem(robot, params, ARM, values, blocks)


def _start_set_up_elsewhere(problem, rng):
    """The solver starts from set-up values 5 mm / 20 mrad off the truth used to simulate."""
    for p in problem.params:
        if p.kind == "auxiliary" and p.vary:
            p.value += rng.uniform(-5e-3, 5e-3) if p.unit == "m" else rng.uniform(-0.02, 0.02)


def test_contact_mix_noise_free_recovery_with_unknown_set_up():
    rng = np.random.default_rng(23)
    problem = contact_problem(rng, 1e-12)
    names = identifiable_names(problem)
    assert {"table.offset", "ball.centre.x", "bar.offset"} <= set(names)
    truth = perturb(problem.params, rng, 1e-3, np.radians(0.1), patterns=[n for n in names if "joint" in n])
    simulate_measurements(problem, truth, rng)
    _start_set_up_elsewhere(problem, rng)
    result = calibrate(problem)
    assert result.success
    assert max(abs(problem.params[n].value - truth[n].value) for n in names) < 1e-9


@pytest.mark.slow
def test_contact_mix_noisy_consistent_with_standard_errors():
    rng = np.random.default_rng(24)
    sigma, trials, chi2 = 1e-5, 20, 0.0
    for _ in range(trials):
        problem = contact_problem(rng, sigma)
        names = identifiable_names(problem)
        truth = perturb(problem.params, rng, 1e-3, np.radians(0.1), patterns=[n for n in names if "joint" in n])
        simulate_measurements(problem, truth, rng)
        _start_set_up_elsewhere(problem, rng)
        result = calibrate(problem, CalibrationOptions(scale_covariance=False))
        assert result.estimated == names
        e = np.array([problem.params[n].value - truth[n].value for n in names])
        chi2 += e @ np.linalg.solve(result.covariance, e)
    dof = trials * len(names)
    assert stats.chi2.ppf(0.0005, dof) < chi2 < stats.chi2.ppf(0.9995, dof)
