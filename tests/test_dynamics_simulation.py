"""Spec seed-004 tests S1-S2: end to end on an aba-simulated UR5 with PID servos and a wall.

The controller is the designed one (docs/dynamics.md, "Stability of the force loop"): a 10 Hz
filter on the force signal and the admittance that keeps a gain margin of 2 and a phase margin of
45 deg for contacts of 1e3 to 1e5 N/m. The ripple in steady contact is tested in
test_dynamics_force_ripple.py."""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.differentiation import TickDifferentiator
from robocal.dynamics.environment import Environment, Wall
from robocal.dynamics.external_force import ExternalForceEstimator
from robocal.dynamics.force_filter import ForceFilter
from robocal.dynamics.force_loop import admittance_for_margins, tangent_loop
from robocal.dynamics.force_sensor import ForceSensorSource
from robocal.dynamics.friction import FrictionModel
from robocal.dynamics.generator import PathGenerator
from robocal.dynamics.instructions import MotionParams, movelf
from robocal.dynamics.simulator import RobotSimulator, servo_gains
from force_cases import Q0, frame_pose

F_DES, V_MAX, A_MAX, L, TS = 20.0, 0.25, 1.0, 0.2, 0.004
BANDWIDTH = 60.0


@pytest.fixture(scope="module")
def ur5():
    return robocal.load_example("ur5")


def run_s(ur5, source, ticks=1200):
    m, fid = ur5.model, ur5.frame_id("tool0")
    act = ActuatorModel([0.12, 0.12, 0.11, 0.09, 0.09, 0.08], [101] * 6, [0.01, -0.02, 0, 0.03, 0, -0.01])
    fr = FrictionModel([3, 3, 2, 1, 1, 0.8], [5, 5, 3, 1, 1, 1], smoothing=0.01)
    start = frame_pose(m, fid)
    u = np.array([1.0, 0, 0])
    env = Environment(Wall(start.translation + 0.03 * u, u, 2e4),            # wall across the path
                      Wall(start.translation + 0.001 * np.array([0, 0, 1.0]), [0, 0, -1.0], 1e4))  # 1 mm into a floor
    gains = servo_gains(m, Q0, BANDWIDTH)
    loop = tangent_loop(m, Q0, fid, gains, u, fr, TS)
    admittance = admittance_for_margins(loop, 1e5, ForceFilter(10.0, TS), min_stiffness=1e3)
    sim = RobotSimulator(m, fid, Q0, act, fr, env, gains, TS, current_noise=0.005, quantisation=1e-3, seed=3)
    ins = movelf(m, fid, Q0, pin.SE3(start.rotation, start.translation + L * u),
                 MotionParams(V_MAX, A_MAX, admittance=admittance, force_filter_hz=10.0), F_DES)
    gen = PathGenerator(m, ins, TS)
    estimator = ExternalForceEstimator(m, fid, act, fr)
    sensor = ForceSensorSource(m, ur5.frame_id("wrist_3_link"), fid)
    diff = TickDifferentiator(TS, "central")
    rng = np.random.default_rng(4)
    wrench, prev_current = np.zeros(6), None
    rows = []
    for _ in range(ticks):
        sp = gen.tick(wrench)
        meas = sim.step(sp.q_des)
        if source == "currents":
            state = diff.push(meas.q_mes)           # central differences: one tick late
            if state is not None and prev_current is not None:
                wrench, _ = estimator.tick(*state, prev_current)
            prev_current = meas.current
        else:
            raw = sensor.raw_from_wrench(meas.q_mes, meas.true_wrench) + rng.normal(scale=0.2, size=6)
            wrench = sensor.wrench_at_tcp(meas.q_mes, raw)
        x, _ = sim.tcp_state()
        rows.append(np.r_[sp.s, sp.sd, sp.sdd, meas.true_wrench[:3] @ u, np.linalg.norm(meas.true_wrench[:3]), x])
    return np.array(rows), start.translation, u, gains


def check(ur5, rows, x0, u, gains):
    s, sd, sdd, f_t, f_norm, x = rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], rows[:, 4], rows[:, 5:8]
    assert np.all(np.abs(sd) * L <= V_MAX * (1 + 1e-12))
    assert np.all(np.abs(sdd) * L <= A_MAX * (1 + 1e-12))
    assert s[-1] < 1.0                                     # stopped at the wall
    steady = f_t[-200:].mean()
    assert abs(steady - F_DES) <= 0.05 * F_DES
    # path deviation: contact force through the servo's Cartesian compliance J Kp^-1 J^T, plus the
    # servo lag v/bandwidth of a second-order loop at the fastest speed reached, both with a factor 2
    J = pin.computeFrameJacobian(ur5.model, ur5.model.createData(), Q0, ur5.frame_id("tool0"),
                                 pin.LOCAL_WORLD_ALIGNED)[:3]
    compliance = np.linalg.eigvalsh(J @ np.diag(1 / gains[0]) @ J.T)[-1]
    rel = x - x0
    deviation = np.linalg.norm(rel - np.outer(rel @ u, u), axis=1)
    bound = 2 * (f_norm.max() * compliance + np.max(np.abs(sd)) * L / BANDWIDTH)
    assert deviation.max() <= bound
    return steady


def test_S1_current_based_force_regulation_against_wall(ur5):
    rows, x0, u, gains = run_s(ur5, "currents")
    check(ur5, rows, x0, u, gains)


def test_S2_force_sensor_variant(ur5):
    rows, x0, u, gains = run_s(ur5, "sensor")
    check(ur5, rows, x0, u, gains)


def test_force_sensor_moves_wrench_to_tcp(ur5):
    m = ur5.model
    flange, tcp = ur5.frame_id("wrist_3_link"), ur5.frame_id("tool0")
    sensor = ForceSensorSource(m, flange, tcp, offset=np.arange(6.0), gain=np.full(6, 2.0),
                               tool_mass=1.5, tool_com=[0, 0, 0.05])
    q = Q0
    d = m.createData()
    pin.framesForwardKinematics(m, d, q)
    f = np.array([10.0, -5.0, 3.0])
    raw = sensor.raw_from_wrench(q, np.r_[f, 0, 0, 0])
    # physics: about the sensor origin the pure TCP force has moment r x f, r from sensor to TCP
    oMs, oMt = d.oMf[flange], d.oMf[tcp]
    corrected = sensor.gain * (raw - sensor.offset)
    weight = oMs.rotation.T @ np.array([0, 0, -9.81 * 1.5])
    r = oMt.translation - oMs.translation
    expected = np.r_[oMs.rotation.T @ f, oMs.rotation.T @ np.cross(r, f)] + np.r_[weight, np.cross([0, 0, 0.05], weight)]
    assert np.allclose(corrected, expected, atol=1e-12)
    assert np.allclose(sensor.wrench_at_tcp(q, raw), np.r_[f, 0, 0, 0], atol=1e-12)
