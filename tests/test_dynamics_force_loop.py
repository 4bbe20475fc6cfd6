"""The force-loop model (force_loop.py) against the simulated robot, the admittance chooser, and
the force filter."""
import numpy as np
import pinocchio as pin
import pytest
from scipy import signal

import robocal
from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.current_force_loop import CurrentForceLoop
from robocal.dynamics.differentiation import TickDifferentiator
from robocal.dynamics.environment import Environment, Wall
from robocal.dynamics.external_force import ExternalForceEstimator
from robocal.dynamics.force_filter import ForceFilter
from robocal.dynamics.force_loop import admittance_for_margins, margins, plant_map, tangent_loop
from robocal.dynamics.friction import FrictionModel
from robocal.dynamics.generator import PathGenerator
from robocal.dynamics.instructions import MotionParams, movelf
from robocal.dynamics.instructions import tick_ik_options
from robocal.model.inverse_kinematics import solve_ik
from robocal.dynamics.simulator import RobotSimulator, servo_gains
from force_cases import Q0, frame_pose

TS, K_WALL = 0.004, 2e4
U = np.array([1.0, 0.0, 0.0])
ACTUATOR = ActuatorModel([0.12, 0.12, 0.11, 0.09, 0.09, 0.08], gear_ratio=[101] * 6)
FRICTION = FrictionModel([3, 3, 2, 1, 1, 0.8], viscous=[5, 5, 3, 1, 1, 1], smoothing=0.01)


@pytest.fixture(scope="module")
def ur5():
    robot = robocal.load_example("ur5")
    return robot, frame_pose(robot.model, robot.frame_id("tool0"))


@pytest.mark.parametrize("current_bandwidth", [None, 2 * np.pi * 150.0])
def test_plant_model_matches_simulated_setpoint_step(ur5, current_bandwidth):
    """A 10 um setpoint step along u, tool touching a wall: the estimate per tick, sim vs model,
    with an ideal and with a 150 Hz first-order current loop.

    The simulator integrates with semi-implicit Euler, first order in its step: the first tick's
    estimate is 35 % off with 4 substeps and converges as 1/substeps (measured 17, 8, 4, 2 % at 8,
    16, 32, 64). With 64 substeps the model must agree within 5 % of the largest value."""
    robot, start = ur5
    m, fid = robot.model, robot.frame_id("tool0")
    none = FrictionModel(np.zeros(6))
    gains = servo_gains(m, Q0)
    sim = RobotSimulator(m, fid, Q0, ACTUATOR, none, Environment(Wall(start.translation, U, K_WALL)), gains,
                         TS, substeps=64, current_bandwidth=current_bandwidth)
    est = ExternalForceEstimator(m, fid, ACTUATOR, none)
    diff = TickDifferentiator(TS, "central")
    A, B, C, D = plant_map(tangent_loop(m, Q0, fid, gains, U, none, TS, current_bandwidth), K_WALL)
    p, q, last, d = np.zeros(A.shape[0]), Q0.copy(), None, m.createData()
    sim_out, model_out = [], []
    for k in range(14):
        r = 1e-5 if k >= 3 else 0.0
        q = solve_ik(m, fid, pin.SE3(start.rotation, start.translation + r * U), q, data=d, **tick_ik_options(1e-10))
        meas = sim.step(q)
        state = diff.push(meas.q_mes)
        w = est.tick(*state, last)[0] if state is not None and last is not None else np.zeros(6)
        last = meas.current
        model_out.append(C @ p + D * r)
        p = A @ p + B * r
        sim_out.append(w[:3] @ U)
    sim_out, model_out = np.array(sim_out), np.array(model_out)
    assert np.max(np.abs(sim_out)) > 1.0                     # the step moved the estimate
    assert np.max(np.abs(sim_out - model_out)) <= 0.05 * np.max(np.abs(sim_out))


def run_contact(ur5, admittance, ticks, substeps=16, noise=0.0, filter_hz=None, wall_at=0.005):
    robot, start = ur5
    m, fid = robot.model, robot.frame_id("tool0")
    sim = RobotSimulator(m, fid, Q0, ACTUATOR, FRICTION,
                         Environment(Wall(start.translation + wall_at * U, U, K_WALL)), servo_gains(m, Q0), TS,
                         substeps=substeps, current_noise=noise, seed=2)
    ins = movelf(m, fid, Q0, pin.SE3(start.rotation, start.translation + 0.05 * U),
                 MotionParams(0.25, 1.0, admittance=admittance, force_filter_hz=filter_hz), 20.0)
    loop = CurrentForceLoop(PathGenerator(m, ins, TS), sim, ExternalForceEstimator(m, fid, ACTUATOR, FRICTION),
                            TickDifferentiator(TS, "central"))
    return np.array([loop.tick()[0].sd * ins.path.length for _ in range(ticks)])


def test_stability_boundary_matches_simulation(ur5):
    """The model's critical admittance (gain margin 1) against a 2e4 N/m wall, no filter: the
    simulated loop settles at 0.8 times it and keeps oscillating at 1.25 times it, at about the
    model's phase-crossover frequency (the limit cycle is bounded by the acceleration limit)."""
    robot, _ = ur5
    loop = tangent_loop(robot.model, Q0, robot.frame_id("tool0"), servo_gains(robot.model, Q0), U, FRICTION, TS)
    probe = margins(loop, K_WALL, 5e-4)
    critical = 5e-4 * probe.gain_margin              # the open loop is proportional to the admittance
    assert probe.stable and 0.5e-3 < critical < 2e-3
    calm = run_contact(ur5, 0.8 * critical, 450)
    ringing = run_contact(ur5, 1.25 * critical, 450)
    # no noise in these runs: a settled loop moves by far less than 0.1 mm/s, a limit cycle by mm/s
    assert np.ptp(calm[-100:]) < 1e-4
    assert np.ptp(ringing[-100:]) > 5e-3
    tail = ringing[-200:] - ringing[-200:].mean()
    freqs = np.fft.rfftfreq(tail.size, TS)
    peak = freqs[np.argmax(np.abs(np.fft.rfft(tail)))]
    assert abs(peak - probe.phase_crossover_hz) <= 0.25 * probe.phase_crossover_hz


def test_admittance_for_margins_is_the_largest_that_keeps_them(ur5):
    robot, _ = ur5
    loop = tangent_loop(robot.model, Q0, robot.frame_id("tool0"), servo_gains(robot.model, Q0), U, FRICTION, TS)
    filt = ForceFilter(10.0, TS)
    a = admittance_for_margins(loop, 1e5, filt, min_stiffness=1e3)
    for k in np.geomspace(1e3, 1e5, 9):        # the chooser samples 5 stiffnesses; check between them too
        mg = margins(loop, k, a, filt)
        assert mg.stable
        assert mg.gain_margin >= 2.0 * 0.97 and mg.phase_margin >= 45.0 - 1.5
    worse = [margins(loop, k, 1.05 * a, filt) for k in np.geomspace(1e3, 1e5, 5)]
    assert min(w.gain_margin for w in worse) < 2.0 or min(w.phase_margin for w in worse) < 45.0


def test_force_filter_matches_scipy_and_its_own_state_space():
    filt = ForceFilter(10.0, TS)
    f = np.array([0.0, 10.0, 40.0])
    z = np.exp(1j * 2 * np.pi * f * TS)
    _, h = signal.sosfreqz(filt.sos, worN=f, fs=1 / TS)
    assert np.allclose(filt.response(z), h, atol=1e-12)
    assert abs(abs(filt.response(np.exp(1j * 2 * np.pi * 10.0 * TS))) - np.sqrt(0.5)) < 1e-9   # -3 dB
    A, B, C, D = filt.state_space()
    ss = np.array([C @ np.linalg.solve(zi * np.eye(A.shape[0]) - A, B) + D for zi in z])
    assert np.allclose(ss, h, atol=1e-12)
    # per-tick filtering of a 6-vector equals scipy's batch filter on each channel
    x = np.random.default_rng(0).normal(size=(50, 6))
    out = np.array([filt.push(row) for row in x])
    assert np.allclose(out, signal.sosfilt(filt.sos, x, axis=0), atol=1e-12)
    with pytest.raises(robocal.errors.InputError):
        ForceFilter(200.0, TS)                          # above Nyquist (125 Hz)


@pytest.mark.parametrize("delay", [0, 1, 2])
def test_gain_margin_agrees_with_the_closed_loop_eigenvalues(ur5, delay):
    """With a sensor delay the open loop's phase passes -180 deg and then -540 deg towards Nyquist, where |L|
    is largest: the gain margin must come from that crossing too. Over an admittance grid, "gain margin > 1"
    and "closed-loop eigenvalues inside the unit circle" must agree (the grid avoids the boundary by a factor
    of 1.05, the margin's interpolation error being far below that)."""
    robot, _ = ur5
    loop = tangent_loop(robot.model, Q0, robot.frame_id("tool0"), servo_gains(robot.model, Q0), U, FRICTION, TS,
                        delay=delay)
    both = 0
    for k in (1e3, 2e4, 1e5):
        for a in np.geomspace(5e-5, 5e-3, 15):
            m = margins(loop, k, a, points=1000)
            if abs(np.log(m.gain_margin)) < np.log(1.05):
                continue
            assert (m.gain_margin > 1) == m.stable, (k, a, m)
            both += m.stable
    assert 0 < both < 45                     # the grid spans stable and unstable loops
