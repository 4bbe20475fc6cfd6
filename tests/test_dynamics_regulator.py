"""Spec seed-004 tests R1-R9: the path generator with the force regulator, perfect servos.

The environment sees the TCP where the setpoint puts it (forward kinematics of q_des) and answers
with the wrench the robot exerts on it, which the generator reads at the next tick.
"""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.dynamics.generator import PathGenerator
from robocal.dynamics.instructions import MotionParams, movejf, movelf
from force_cases import Q0, frame_pose

TS = 0.004
L = 0.2
IK_TOL = 1e-10
WALL = 0.02          # m along the line: contact after about 0.35 s


@pytest.fixture(scope="module")
def ur5():
    return robocal.load_example("ur5")


def line_generator(robot, force, direction=(1.0, 0.0, 0.0), **params):
    fid = robot.frame_id("tool0")
    start = frame_pose(robot.model, fid)
    target = pin.SE3(start.rotation, start.translation + L * np.asarray(direction))
    kw = dict(v_max=0.25, a_max=1.0) | params
    ins = movelf(robot.model, fid, Q0, target, MotionParams(**kw), force)
    return PathGenerator(robot.model, ins, TS, IK_TOL), start.translation.copy(), np.asarray(direction)


def run(robot, gen, env, ticks):
    """Returns s, sd, sdd, eps, sd_max, sdd_max (ticks,) and tcp positions (ticks, 3)."""
    m, d, fid = robot.model, robot.model.createData(), gen.instruction.frame_id
    out, xs = [], []
    x_prev = None
    wrench = np.zeros(6)
    for _ in range(ticks):
        sp = gen.tick(wrench)
        pin.framesForwardKinematics(m, d, sp.q_des)
        x = d.oMf[fid].translation.copy()
        v = np.zeros(3) if x_prev is None else (x - x_prev) / TS
        wrench = env(x, v)
        x_prev = x
        out.append([sp.s, sp.sd, sp.sdd, sp.eps, sp.sd_max, sp.sdd_max])
        xs.append(x)
    return np.array(out).T, np.array(xs)


def free(x, v):
    return np.zeros(6)


def wall(x0, u, position, stiffness, normal=None):
    """Spring along the tangent beyond `position` (m along the line); optional constant normal push."""
    def env(x, v):
        w = np.zeros(6)
        w[:3] = stiffness * max(0.0, (x - x0) @ u - position) * u
        if normal is not None:
            w[:3] += normal
        return w
    return env


def test_R1_free_space_line(ur5):
    gen, x0, u = line_generator(ur5, 10.0, admittance=1.0)
    (s, sd, sdd, *_), x = run(ur5, gen, free, 260)
    moving = s < 1.0                                      # the patent has no braking at s = 1
    assert np.all(np.abs(sd) * L <= 0.25 * (1 + 1e-12))
    assert np.all(np.abs(sdd[moving]) * L <= 1.0 * (1 + 1e-12))
    speed = np.linalg.norm(np.diff(x, axis=0), axis=1) / TS
    assert np.all(speed <= 0.25 + 4 * IK_TOL / TS)        # measured on the IK output
    assert np.max(sd) * L == pytest.approx(0.25, rel=1e-12)  # cruises at v_max
    t_end = (np.argmax(s >= 1.0) + 1) * TS
    assert abs(t_end - (L / 0.25 + 0.25 / (2 * 1.0))) <= 2 * TS


def test_R1_braking_stops_within_limits(ur5):
    gen, *_ = line_generator(ur5, 10.0, admittance=1.0, braking=True)
    (s, sd, sdd, *_), _ = run(ur5, gen, free, 300)
    assert s[-1] == 1.0 and sd[-1] == 0.0
    assert np.all(np.abs(sd) * L <= 0.25 * (1 + 1e-12))
    assert np.max(np.abs(sdd)) * L <= 1.0 * (1 + 1e-12)      # the stop included


def wall_run(ur5, gain_product, ticks=500, normal=None, f_des=30.0, k_e=1e5):
    admittance = gain_product / (TS * k_e)                # g = T_s K L k_e, K L = admittance
    gen, x0, u = line_generator(ur5, f_des, admittance=admittance)
    env = wall(x0, u, WALL, k_e, normal)
    out, x = run(ur5, gen, env, ticks)
    force = k_e * np.maximum(0.0, (x - x0) @ u - WALL)
    return out, x, force, gen


def distance_to_line(x, x0, u):
    rel = x - x0
    return np.linalg.norm(rel - np.outer(rel @ u, u), axis=1)


def test_R2_wall_converges_to_setpoint_and_R7_shape(ur5):
    (s, sd, *_), x, force, gen = wall_run(ur5, 0.8)
    assert abs(force[-1] - 30.0) <= 1e-3 * 30.0
    assert abs(sd[-1]) * L < 1e-6
    # R7: the tool never leaves the line, whatever the force history
    x0 = gen.instruction.path.x0
    assert np.max(distance_to_line(x, x0, np.array([1.0, 0, 0]))) <= 2 * IK_TOL


def test_R3_over_force_retreats_but_never_below_start(ur5):
    gen, x0, u = line_generator(ur5, 10.0, admittance=0.01)
    push = {"on": False}

    def env(x, v):
        w = np.zeros(6)
        if push["on"]:
            w[:3] = 30.0 * u                                 # the load resists with 30 N
        return w
    (s1, *_), _ = run(ur5, gen, env, 100)
    push["on"] = True
    (s, sd, *_), _ = run(ur5, gen, env, 300)
    assert s1[-1] > 0.1
    assert np.min(sd) < 0 and s[-1] == 0.0 and np.all(s >= 0.0)


def test_R4_viscous_load_steady_state(ur5):
    f_des, b, kl = 20.0, 200.0, 0.0025
    gen, x0, u = line_generator(ur5, f_des, admittance=kl)
    (s, sd, *_), x = run(ur5, gen, lambda x, v: np.r_[b * (v @ u) * u, 0, 0, 0], 400)
    v_expected = kl * f_des / (1 + kl * b)
    assert sd[-1] * L == pytest.approx(v_expected, rel=1e-9)
    assert b * sd[-1] * L == pytest.approx(20.0 / 3.0, rel=1e-9)     # 6.667 N, spec §10
    assert s[-1] < 1.0


def test_R5_gain_limit(ur5):
    *_, force_stable, _ = wall_run(ur5, 0.8, ticks=500)
    *_, force_unstable, _ = wall_run(ur5, 2.4, ticks=500)
    tail = slice(-100, None)
    assert np.max(np.abs(force_stable[tail] - 30.0)) <= 1e-3 * 30
    assert np.max(np.abs(force_unstable[tail] - 30.0)) > 0.1 * 30       # keeps oscillating


def test_R6_normal_force_does_not_change_progress(ur5):
    (plain, *_), *_ = wall_run(ur5, 0.8, ticks=300)
    (pushed, *_), *_ = wall_run(ur5, 0.8, ticks=300, normal=np.array([0.0, 40.0, -25.0]))
    assert np.allclose(plain, pushed, rtol=0, atol=1e-12)


def test_R8_movejf_keeps_axes_proportional(ur5):
    fid = ur5.frame_id("tool0")
    q1 = Q0 + np.array([0.3, -0.2, 0.25, 0.1, -0.15, 0.2])
    ins = movejf(ur5.model, fid, Q0, q1, MotionParams(v_max=0.25, a_max=1.0, admittance=0.002), 15.0)
    gen = PathGenerator(ur5.model, ins, TS)
    rng = np.random.default_rng(8)
    for _ in range(200):
        sp = gen.tick(np.r_[rng.normal(scale=20, size=3), 0, 0, 0])
        ratio = (sp.q_des - Q0) / (q1 - Q0)
        assert np.ptp(ratio) <= 1e-12
        assert ratio[0] == pytest.approx(sp.s, abs=1e-12)


def test_R9_hand_guiding_with_zero_setpoint(ur5):
    gen, x0, u = line_generator(ur5, 0.0, admittance=0.005)
    (s, sd, *_), x = run(ur5, gen, lambda x, v: np.r_[-15.0 * u, 0, 0, 0], 100)   # operator pushes +u
    assert np.all(sd[1:] > 0) and s[-1] > 0            # the first tick has no force reading yet
    (s0, *_), _ = run(ur5, line_generator(ur5, 0.0, admittance=0.005)[0], free, 50)
    assert np.all(s0 == 0.0)                                                       # nobody pushes: no motion
