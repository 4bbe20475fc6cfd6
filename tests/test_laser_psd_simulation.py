"""Seed 001: noise statistics (test 8), the servo (test 9), averaging (test 10), the whole acquisition."""
import numpy as np
import pytest
from scipy import stats

from laser_psd_cases import DELTA_TRUE, DIRECTION, MOUNT, ROLL, TARGET, exact_readings, joints, plans, robot, truth
from robocal.estimation.calibrate import calibrate
from robocal.errors import InputError
from robocal.model.kinematics import ModelState
from robocal.systems.laser_psd.calibration import reading_noise_covariance, zero_offset_problem
from robocal.systems.laser_psd.plans import PlannedPose, plan_configurations
from robocal.systems.laser_psd.simulation import PSD, SimRobot, acquire, average_reads, servo_to_center
from robocal.model.parameters import robot_parameters

SIGMA_Q = np.radians(0.0005)      # per averaged reading (the spec's per-read model: test_laser_psd_monte_carlo.py)
FREE = [f"joint_{i}.offset" for i in range(2, 7)]


def _fitted(design):
    q = exact_readings(design)
    problem = zero_offset_problem(robot(), joints(), q, MOUNT, fixed_joints=["joint_1"])
    calibrate(problem)
    return problem, q


def test_three_fans_beat_the_patent_fan_on_joint_2():
    sd = {}
    for design in ("patent", "three_fans"):
        problem, _ = _fitted(design)
        cov = reading_noise_covariance(problem, SIGMA_Q)
        idx = [problem.params.free_names.index(n) for n in FREE]
        sd[design] = np.sqrt(np.diag(cov)[idx])
    # spec 6.7: about 10x better on joint 2 (0.145 -> 0.011 deg); the test asks for at least 5x
    assert sd["patent"][0] / sd["three_fans"][0] > 5


def test_monte_carlo_errors_match_the_predicted_standard_errors():
    problem, q = _fitted("three_fans")
    x_hat = problem.params.free_values()
    names = problem.params.free_names
    idx = [names.index(n) for n in FREE]
    cov = reading_noise_covariance(problem, SIGMA_Q)[np.ix_(idx, idx)]
    rng = np.random.default_rng(8)
    trials = 100
    errors = []
    for _ in range(trials):
        problem.values = q + rng.normal(0.0, SIGMA_Q, q.shape)
        problem.params.set_free_values(x_hat)        # warm start at the noise-free solution
        result = calibrate(problem)
        assert result.solve.success
        errors.append([problem.params[n].value - problem_truth for n, problem_truth in zip(FREE, DELTA_TRUE[1:])])
    E = np.array(errors)
    # Per offset, RMS^2 / sd^2 ~ chi2(T)/T: its square root has a spread of 1/sqrt(2T) = 0.071 for T = 100;
    # allow 4 spreads (+-0.28) plus 2 % for the linearisation.
    ratio = np.sqrt(np.mean(E ** 2, axis=0)) / np.sqrt(np.diag(cov))
    assert np.all(np.abs(ratio - 1) < 0.30), ratio
    # jointly: sum of e^T C^-1 e over the trials ~ chi2(5 T); two-sided 99.9 % band
    chi2 = np.einsum("ti,ij,tj->", E, np.linalg.inv(cov), E)
    assert stats.chi2.ppf(0.0005, 5 * trials) < chi2 < stats.chi2.ppf(0.9995, 5 * trials)


def _sim(noise=0.0, seed=1):
    return SimRobot(robot(), truth(), joints(), MOUNT, reading_noise=noise, rng=np.random.default_rng(seed))


def _jog(offset):
    """A start whose TRUE beam hits the PSD `offset` (m, base frame) away from its centre."""
    ms = ModelState(robot(), truth(), joints())
    return plan_configurations(robot(), ms, joints(), MOUNT, [PlannedPose(np.eye(3), 0.35, 0, 0.0)],
                               TARGET + offset, DIRECTION, ROLL)[0]


def test_servo_centres_a_spot_that_starts_3_mm_off():
    psd = PSD(TARGET, -DIRECTION)
    sim = _sim()
    sim.move(_jog(np.array([0.0, 0.003, 0.0])))
    nominal = ModelState(robot(), robot_parameters(robot(), joints(), "offsets"), joints())
    r = servo_to_center(sim, psd, nominal, tol=1e-6)
    assert np.linalg.norm(r.spots[0]) > 2.5e-3
    assert r.converged and r.iterations <= 20 and np.linalg.norm(r.spots[-1]) < 1e-6
    o, u = sim.beam()
    assert np.linalg.norm(np.cross(TARGET - o, u)) < 1e-6 + psd.resolution


@pytest.mark.parametrize("design", ["patent", "three_fans"])
def test_acquisition_converges_on_every_pose_and_calibrates(design):
    psd = PSD(TARGET, -DIRECTION)
    sim = _sim(noise=SIGMA_Q * np.sqrt(3), seed=2)     # three reads per pose average to SIGMA_Q
    nominal = robot_parameters(robot(), joints(), "offsets")
    acq = acquire(robot(), nominal, joints(), sim, psd, plans()[design], DIRECTION, _jog(np.zeros(3)), ROLL,
                  n_reads=3)
    assert all(r.converged and r.iterations <= 20 for r in acq.servo)
    assert all(np.max(np.abs(r.spots[-1])) <= psd.resolution for r in acq.servo)
    # centred within the resolution (0.1 um per axis, at most 45 deg incidence): beam within 0.2 um
    assert acq.miss.max() < 2 * np.sqrt(2) * psd.resolution
    problem = zero_offset_problem(robot(), joints(), acq.readings, MOUNT, fixed_joints=["joint_1"])
    calibrate(problem)
    cov = reading_noise_covariance(problem, SIGMA_Q)
    names = problem.params.free_names
    for n, d in zip(FREE, DELTA_TRUE[1:]):
        # 5 sigma of the predicted reading-noise error; the servo's 0.2 um adds < 1 % of it
        assert abs(problem.params[n].value - d) < 5 * np.sqrt(cov[names.index(n), names.index(n)])


def test_averaging_reads_divides_the_noise_by_sqrt_n():
    sim = _sim(noise=1e-4, seed=3)
    sim.move(np.zeros(6))
    means = np.array([average_reads(sim, 3) for _ in range(2000)])
    # sd of a sample sd from 2000 x 6 draws: 1/sqrt(2 * 12000) = 0.65 %; allow 4 % (6 spreads)
    assert abs(means.std() / (1e-4 / np.sqrt(3)) - 1) < 0.04
    for bad in (1, 0, 2.5):
        with pytest.raises(InputError):
            average_reads(sim, bad)
