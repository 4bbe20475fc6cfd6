"""Steady contact without a limit cycle: the ripple of the force estimate and of the path speed.

Scenario of test S1 (UR5, PID servos, a 2e4 N/m wall across the path, force from noisy quantised
currents, 4 ms ticks), with the controller designed as docs/dynamics.md describes: a 10 Hz
Butterworth filter on the estimate and the largest admittance that keeps a gain margin of 2 and a
phase margin of 45 deg against contacts of 1e3 to 1e5 N/m (force_loop.admittance_for_margins).
"""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.current_force_loop import CurrentForceLoop
from robocal.dynamics.differentiation import TickDifferentiator
from robocal.dynamics.environment import Environment, Wall
from robocal.dynamics.external_force import ExternalForceEstimator
from robocal.dynamics.force_filter import ForceFilter
from robocal.dynamics.force_loop import admittance_for_margins, tangent_loop
from robocal.dynamics.friction import FrictionModel
from robocal.dynamics.generator import PathGenerator
from robocal.dynamics.instructions import MotionParams, movelf
from robocal.dynamics.simulator import RobotSimulator, servo_gains
from force_cases import Q0, frame_pose

F_DES, TS, L = 20.0, 0.004, 0.2
U = np.array([1.0, 0.0, 0.0])
NOISE, LSB = 0.005, 1e-3          # current noise std and quantisation step, A
FILTER_HZ = 10.0
TICKS, WINDOW = 1500, 250         # 6 s; the steady window is the last second


@pytest.fixture(scope="module")
def contact_run():
    robot = robocal.load_example("ur5")
    m, fid = robot.model, robot.frame_id("tool0")
    act = ActuatorModel([0.12, 0.12, 0.11, 0.09, 0.09, 0.08], [101] * 6, [0.01, -0.02, 0, 0.03, 0, -0.01])
    fr = FrictionModel([3, 3, 2, 1, 1, 0.8], [5, 5, 3, 1, 1, 1], smoothing=0.01)
    gains = servo_gains(m, Q0)
    loop = tangent_loop(m, Q0, fid, gains, U, fr, TS)
    admittance = admittance_for_margins(loop, 1e5, ForceFilter(FILTER_HZ, TS), min_stiffness=1e3)
    start = frame_pose(m, fid)
    env = Environment(Wall(start.translation + 0.03 * U, U, 2e4),
                      Wall(start.translation + 0.001 * np.array([0, 0, 1.0]), [0, 0, -1.0], 1e4))
    sim = RobotSimulator(m, fid, Q0, act, fr, env, gains, TS, current_noise=NOISE, quantisation=LSB, seed=3)
    ins = movelf(m, fid, Q0, pin.SE3(start.rotation, start.translation + L * U),
                 MotionParams(0.25, 1.0, admittance=admittance, force_filter_hz=FILTER_HZ), F_DES)
    loop = CurrentForceLoop(PathGenerator(m, ins, TS), sim, ExternalForceEstimator(m, fid, act, fr),
                            TickDifferentiator(TS, "central"))
    rows = []
    for _ in range(TICKS):
        sp, meas = loop.tick()
        rows.append([sp.force, sp.sd * L, meas.true_wrench[:3] @ U])
    # noise of the unfiltered tangential estimate: F_u = dq^T tau with dq = J^-1 [u; 0], and
    # tau = K (I + n), n white with variance NOISE^2 + LSB^2/12 (quantisation) on each joint
    J = pin.computeFrameJacobian(m, m.createData(), Q0, fid, pin.LOCAL_WORLD_ALIGNED)
    dq = np.linalg.solve(J, np.r_[U, 0, 0, 0])
    sigma_raw = np.linalg.norm(dq @ act.gain) * np.sqrt(NOISE**2 + LSB**2 / 12)
    sigma = sigma_raw * ForceFilter(FILTER_HZ, TS).noise_gain()
    return np.array(rows), admittance, sigma


def test_contact_is_reached_and_held(contact_run):
    rows, _, _ = contact_run
    touching = np.nonzero(rows[:, 2] > 0)[0]
    assert touching.size and touching[0] < TICKS - 2 * WINDOW       # in contact well before the window
    assert np.all(rows[-WINDOW:, 2] > 0)


def test_estimate_stays_within_one_newton(contact_run):
    rows, _, sigma = contact_run
    estimate = rows[-WINDOW:, 0]
    assert np.max(np.abs(estimate - F_DES)) <= 1.0                # the requirement
    # ripple: a Gaussian stays within +-4.5 sigma at all 250 samples with probability > 0.998, so
    # the peak-to-peak of pure noise is below 9 sigma; a limit cycle is not
    assert np.ptp(estimate) <= 9 * sigma, (np.ptp(estimate), sigma)


def test_path_speed_has_no_sustained_oscillation(contact_run):
    rows, admittance, sigma = contact_run
    speed = rows[-WINDOW:, 1]
    # unsaturated, the regulator's speed is admittance x force error: the same 9 sigma bound
    assert np.ptp(speed) <= admittance * 9 * sigma, (np.ptp(speed), admittance * 9 * sigma)
    assert abs(speed.mean()) <= admittance * 4.5 * sigma        # and it does not creep


def test_true_force_holds_the_setpoint(contact_run):
    rows, _, sigma = contact_run
    true = rows[-WINDOW:, 2]
    # the estimate the loop nulls is the true force plus noise of std sigma (and the friction and
    # model terms are exact in this simulation): the mean error of the true force is of that order
    assert abs(true.mean() - F_DES) <= 4.5 * sigma
    assert np.ptp(true) <= 9 * sigma
