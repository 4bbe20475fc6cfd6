"""Force regulation that survives stiction (issue 35, part 1): the stick-slip plant, the sensor delay,
the contact observer, and the regulation at the corners of the model-error range.

The plant (robocal.dynamics.force_scenario): UR5 with PID servos, joints that stick up to 1.25 x their
Coulomb friction, 5 mA current noise, one tick of sensor delay, a 2e4 N/m wall 30 mm ahead, 20 N.
"""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.contact_observer import ContactForceObserver
from robocal.dynamics.environment import Environment
from robocal.dynamics.force_filter import ForceFilter
from robocal.dynamics.force_scenario import Plant, deburr, scaled_actuator, scaled_friction
from robocal.dynamics.simulator import RobotSimulator, servo_gains
from robocal.dynamics.stick_slip import StickSlipFriction
from force_cases import Q0

F_DES, TOL = 20.0, 0.05              # the requirement: +-5 % of the setpoint in contact
COULOMB = np.array([3, 3, 2, 1, 1, 0.8])
TICKS, WINDOW = 1100, 250            # contact at about 2 s; the steady window is the last second


@pytest.fixture(scope="module")
def plant():
    robot = robocal.load_example("ur5")
    m = robot.model
    return Plant(m, robot.frame_id("tool0"), Q0, ActuatorModel([0.12, 0.12, 0.11, 0.09, 0.09, 0.08], gear_ratio=[101] * 6),
                 StickSlipFriction(COULOMB, 1.25 * COULOMB, [5, 5, 3, 1, 1, 1], 0.01), servo_gains(m, Q0))


def test_stick_slip_holds_below_breakaway_and_slides_at_coulomb():
    """Implicit dry friction on a coupled 2-joint inertia: the result is the minimiser's KKT point."""
    fr = StickSlipFriction([1.0, 2.0], breakaway=[1.5, 2.5], stribeck_velocity=0.01)
    M, dt = np.array([[2.0, 0.5], [0.5, 1.0]]), 1e-3
    # from rest, a push whose holding torque M v_free/dt stays below breakaway: both stay exactly at rest
    v_free = np.linalg.solve(M, [1.2, -2.0]) * dt
    assert np.all(fr.implicit_velocity(M, v_free, np.zeros(2), dt) == 0.0)
    # a push beyond breakaway on joint 0 only: joint 0 slides, friction there equals -breakaway sign(v)
    v_free = np.linalg.solve(M, [4.0, 0.0]) * dt
    v = fr.implicit_velocity(M, v_free, np.zeros(2), dt)
    friction = M @ (v_free - v) / dt
    assert v[0] > 0 and abs(friction[0] - 1.5) < 1e-9
    assert v[1] == 0.0 and abs(friction[1]) <= 2.5            # joint 1 held by stiction
    # sliding fast: the level is Coulomb (the Stribeck excess has decayed)
    v_fast = np.array([1.0, 0.0])
    v = fr.implicit_velocity(M, v_fast + np.linalg.solve(M, [0.0, 0.0]) * dt, v_fast, dt)
    assert abs((M @ (v_fast - v) / dt)[0] - 1.0) < 1e-9


def test_measurement_delay_returns_the_previous_tick(plant):
    sims = [RobotSimulator(plant.model, plant.frame_id, Q0, plant.actuator, plant.friction, Environment(),
                           plant.gains, measurement_delay=d) for d in (0, 1)]
    target = Q0 + 0.01
    now, late = zip(*[(sims[0].step(target), sims[1].step(target)) for _ in range(3)])
    assert np.allclose(late[0].q_mes, Q0)                     # before the first period: the rest state
    assert np.allclose(late[2].q_mes, now[1].q_mes) and np.allclose(late[2].current, now[1].current)


def test_observer_drops_stuck_joints_and_fits_the_contact_line():
    """Synthetic torques: a stuck joint's row carries an unknown friction torque and must be left out."""
    rng = np.random.default_rng(0)
    J = rng.normal(size=(3, 6))
    u = np.array([1.0, 0.0, 0.0])
    obs = ContactForceObserver(F_DES)
    f = np.array([12.0, -3.0, 1.0])
    torque = J.T @ f
    torque[4] += 5.0                                          # static friction hidden in joint 4
    rows = np.ones(6, bool)
    rows[4] = False
    assert abs(obs.force_from_rows(torque, J, u, rows) - 12.0) < 1e-9
    assert obs.force_from_rows(torque, J, u, np.r_[True, True, False, False, False, False]) is None   # < 3 rows
    # contact line: trusted samples on F = k x + b are fitted exactly; an untrusted tick reads the line
    obs.in_contact, obs.tare, obs.signs = True, np.zeros(6), np.ones(6)
    for x in np.linspace(0.0, 5e-4, 8):
        obs.update(J.T @ np.array([2e4 * x + 3.0, 0, 0]), J, u, x, np.full(6, 0.01))
    k, b = obs.contact_line
    assert abs(k - 2e4) < 1e-6 * 2e4 and abs(b - 3.0) < 1e-9
    assert abs(obs.update(np.zeros(6), J, u, 0.0, np.zeros(6), x_cmd=6e-4) - (2e4 * 6e-4 + 3.0)) < 1e-9


def steady_contact_ok(run, admittance):
    """(ok, reason): the true force within +-5 % over the steady window and no limit cycle. A limit
    cycle shows in the path speed: without one, the speed is admittance x (noise of the filtered
    estimate), below 9 sigma peak to peak (the ripple test's bound, sigma = 0.09 N for 5 mA at 10 Hz)."""
    lo, hi = run.true_band
    sigma = 0.209 * ForceFilter(10.0).noise_gain()            # |dq^T K| x 5 mA: raw tangential noise
    bound = admittance * 9 * sigma * 1e3                       # mm/s
    reasons = []
    if not (abs(lo - F_DES) <= TOL * F_DES and abs(hi - F_DES) <= TOL * F_DES):
        reasons.append(f"true force {lo:.2f}..{hi:.2f} N outside +-5 %")
    if run.speed_ripple > bound:
        reasons.append(f"speed ripple {run.speed_ripple:.2f} mm/s above {bound:.2f}: a limit cycle")
    return not reasons, "; ".join(reasons)


ADMITTANCE = 7.18e-4       # admittance_for_margins with the one-tick delay (benchmarks/force_regulation_realism.py)


def corner_run(plant, friction_factor, kt_factor):
    return deburr(plant, scaled_friction(plant.friction, friction_factor), scaled_actuator(plant.actuator, kt_factor),
                  admittance=ADMITTANCE, wall_at=0.03, ticks=TICKS, window=WINDOW)


@pytest.mark.parametrize("friction_factor, kt_factor", [(0.5, 1.05), (1.5, 0.95), (1.0, 1.0)])
def test_no_limit_cycle_and_no_free_space_bias_at_the_corners(plant, friction_factor, kt_factor):
    """Friction -50 % / +50 % with the torque constant +5 % / -5 %, and the exact model, with stiction,
    delay and noise: in steady contact the path does not oscillate, and in free space the force the
    regulator sees is 0 within the noise (the tare). The former design fails the first on the exact
    model (a stick-slip limit cycle, 10.6 mm/s peak to peak; see the report)."""
    run = corner_run(plant, friction_factor, kt_factor)
    ok, reason = steady_contact_ok(run, ADMITTANCE)
    assert "limit cycle" not in reason, reason
    assert np.all(run.rows[-WINDOW:, 2] > 0)                  # still in contact
    assert abs(run.free_bias) < 4.5 * 0.209 / np.sqrt(50)      # 4.5 sigma of a 50-tick tare of the raw noise


@pytest.mark.xfail(strict=True, reason="known shortfall (docs/dynamics.md, 'Under stiction'): with friction "
                   "+50 % the contact line puts the true force 12 % high")
def test_force_band_at_the_friction_corner(plant):
    ok, reason = steady_contact_ok(corner_run(plant, 1.5, 1.0), ADMITTANCE)
    assert ok, reason
