"""Monte Carlo of the laser/PSD zero-offset fit under joint-reading noise (docs/laser_psd.md, "Accuracy").

Noise model (the spec's simulator): every single joint read carries Gaussian noise of sd `sigma_read`
(rad, every joint); a pose's reading is the mean of `n_reads` such reads, so it carries sigma_read /
sqrt(n_reads). The statistic reported is the RMS of the estimation error over the trials, per offset,
next to the linearised prediction (reading_noise_covariance) of the same quantity. Trial k draws its
noise from its own seed (robocal.estimation.parallel_map), so the study runs the same on a Dask cluster.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.errors import InputError, RobocalError
from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.parallel_map import monte_carlo
from robocal.estimation.problem import Problem
from robocal.model.kinematics import ModelState
from robocal.residuals.base import basis_from_normal
from robocal.systems.laser_psd.calibration import reading_noise_covariance, zero_offset_problem
from robocal.systems.laser_psd.plans import plan_configurations


@dataclass
class MonteCarloResult:
    names: list[str]              # the offsets reported, e.g. joint_2.offset .. joint_6.offset
    errors: np.ndarray            # (trials, len(names)) estimate - truth, rad
    predicted_sd: np.ndarray      # (len(names),) linearised sd of the estimate, rad

    @property
    def rms(self) -> np.ndarray:
        return np.sqrt(np.mean(self.errors ** 2, axis=0))


def averaged_reading_noise(rng, shape, sigma_read: float, n_reads: int) -> np.ndarray:
    """Noise of a pose's reading: the mean of n_reads independent reads' noise (drawn read by read)."""
    if int(n_reads) != n_reads or n_reads < 1:
        raise InputError(f"n_reads must be a positive integer, got {n_reads}", field="n_reads")
    return rng.normal(0.0, sigma_read, (int(n_reads),) + tuple(shape)).mean(axis=0)


@dataclass
class OffsetTrial:
    """One Monte-Carlo trial: noisy readings, a fit from the noise-free solution, the offsets' errors.
    Works on its own copy of the problem, so trials are independent of each other and of their order."""
    problem: Problem              # solved on the noise-free readings
    exact_readings: np.ndarray
    sigma_read: float
    n_reads: int
    names: list[str]
    truth: dict

    def __call__(self, rng: np.random.Generator) -> list[float]:
        problem = copy.deepcopy(self.problem)
        problem.values = self.exact_readings + averaged_reading_noise(rng, self.exact_readings.shape,
                                                                      self.sigma_read, self.n_reads)
        calibrate(problem)
        return [problem.params[n].value - self.truth[n] for n in self.names]


def offset_monte_carlo(robot, joints, exact_readings, mount, truth_offsets, sigma_read: float, n_reads: int = 3,
                       trials: int = 40, seed: int = 0, fixed_joints=None, scheduler: str | None = None,
                       workers: int | None = None) -> MonteCarloResult:
    """Fit the offsets on `trials` noisy copies of `exact_readings` (readings at which the true beams pass
    exactly through the PSD centre). truth_offsets: (len(joints),) rad. Joint 1 is held (it is a gauge of
    the unknown point) unless `fixed_joints` says otherwise; every other offset is reported.
    Each trial starts from the noise-free solution, so the spread is the noise's alone. Trial k's noise
    comes from the k-th child of SeedSequence(seed); `scheduler`/`workers` spread the trials over Dask
    (docs/fleet.md) with the same results as the serial run."""
    fixed = [joints[0]] if fixed_joints is None else list(fixed_joints)
    problem = zero_offset_problem(robot, joints, exact_readings, mount, fixed_joints=fixed)
    calibrate(problem, CalibrationOptions(regularisation="none"))   # what the data alone determine
    names = [f"{j}.offset" for j in joints if j not in fixed]
    free = problem.params.free_names
    idx = [free.index(n) for n in names]
    cov = reading_noise_covariance(problem, sigma_read / np.sqrt(n_reads))
    truth = dict(zip([f"{j}.offset" for j in joints], np.asarray(truth_offsets, dtype=float)))
    trial = OffsetTrial(problem, np.asarray(exact_readings, dtype=float), sigma_read, n_reads, names, truth)
    errors = monte_carlo(trial, int(trials), seed, scheduler, workers)
    return MonteCarloResult(names, np.array(errors).reshape(int(trials), len(names)),
                            np.sqrt(np.diag(cov)[idx]))


def predicted_offset_sd(robot, joints, truth_params, mount, plan, target, direction, roll: float,
                        sigma_reading: float) -> np.ndarray:
    """Linearised sd (rad) of joints[1:]'s offsets for a plan realised on the true robot `truth_params`
    (beams exactly through `target`), reading noise sigma_reading per averaged reading. Cheap (no Monte
    Carlo): used to sweep the set-up choices the spec leaves open (roll of the beam frame, fan axes)."""
    ms = ModelState(robot, truth_params, joints)
    q = plan_configurations(robot, ms, joints, mount, plan, target, direction, roll)
    problem = zero_offset_problem(robot, joints, q, mount, fixed_joints=[joints[0]])
    calibrate(problem, CalibrationOptions(regularisation="none"))   # what the data alone determine
    free = problem.params.free_names
    idx = [free.index(f"{j}.offset") for j in joints[1:]]
    return np.sqrt(np.diag(reading_noise_covariance(problem, sigma_reading))[idx])


def sweep_predicted_sd(robot, joints, truth_params, mount, target, direction, rolls, plan_makers: dict,
                       sigma_reading: float) -> dict:
    """{(plan name, roll): predicted sd of joints[1:]'s offsets (rad)} over rolls of the beam frame.
    plan_makers: {name: f(reference beam frame rotation R) -> plan}, so fan axes may be tied to the beam
    frame. A set-up the robot cannot reach (or an IK failure along a sweep) is left out."""
    out = {}
    for roll in rolls:
        R = basis_from_normal(direction) @ pin.exp3(np.array([0.0, 0.0, roll]))
        for name, make in plan_makers.items():
            try:
                out[(name, float(roll))] = predicted_offset_sd(robot, joints, truth_params, mount, make(R), target,
                                                               direction, roll, sigma_reading)
            except RobocalError:
                continue
    return out
