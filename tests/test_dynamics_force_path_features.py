"""Path features around the force regulator: joint limits on Cartesian paths (projection of the
velocity/acceleration limits through h(s) = IK(f(s)), refusal past a position limit), blending of
consecutive segments, orientation-rate limits."""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.dynamics.blending import BlendedPath
from robocal.dynamics.generator import PathGenerator
from robocal.dynamics.instructions import MotionParams, movecf, movelf
from robocal.dynamics.instructions import tick_ik_options
from robocal.model.inverse_kinematics import solve_ik
from robocal.dynamics.joint_projection import joint_derivatives
from robocal.dynamics.limits import project_limits
from robocal.dynamics.path import LinearPath
from robocal.errors import InputError
from force_cases import Q0, frame_pose

TS = 0.004
RATIO_TOL = 1 + 1e-12


@pytest.fixture(scope="module")
def ur5():
    robot = robocal.load_example("ur5")
    return robot, frame_pose(robot.model, robot.frame_id("tool0"))


def turning_line(start):
    end = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, 0.6) @ start.rotation, start.translation + [0.1, 0.05, 0.0])
    return end, LinearPath(start, end)


def corner_path(start, radius=0.02):
    x0 = start.translation
    return BlendedPath([x0, x0 + [0.08, 0, 0], x0 + [0.08, 0.08, 0], x0 + [0.16, 0.1, 0.02]], radius, start.rotation)


def run_free(robot, ins, ticks):
    gen = PathGenerator(robot.model, ins, TS)
    return gen, [gen.tick(np.zeros(6)) for _ in range(ticks)]


# ---- joint limits on Cartesian paths ---------------------------------------------------------------
def test_joint_derivatives_match_finite_differences_of_ik(ur5):
    robot, start = ur5
    m, d, fid = robot.model, robot.model.createData(), robot.frame_id("tool0")
    h = 1e-3
    for path in (turning_line(start)[1], corner_path(start)):
        for s in (0.2, 0.5, 0.77):
            q = {k: solve_ik(m, fid, path.pose(s + k * h), Q0, data=d, **tick_ik_options(1e-13)) for k in (-1, 0, 1)}
            _, df, ddf = path.derivatives(s)
            dh, ddh = joint_derivatives(m, d, fid, q[0], df, ddf, *path.angular_derivatives(s))
            # central differences: truncation h^2/6 |h'''| ~ 1e-6 here; IK residual 1e-13/h^2 = 1e-7
            assert np.allclose((q[1] - q[-1]) / (2 * h), dh, atol=1e-5 * max(1.0, np.abs(dh).max()))
            assert np.allclose((q[1] - 2 * q[0] + q[-1]) / h**2, ddh, atol=1e-4 * max(1.0, np.abs(ddh).max()))


def test_cartesian_line_respects_projected_joint_limits(ur5):
    robot, start = ur5
    m, fid = robot.model, robot.frame_id("tool0")
    end, _ = turning_line(start)
    qd_max, qdd_max = np.full(6, 0.3), np.full(6, 1.5)
    plain = movelf(m, fid, Q0, end, MotionParams(0.25, 1.0, admittance=1.0), 10.0)
    limited = movelf(m, fid, Q0, end, MotionParams(0.25, 1.0, admittance=1.0, qd_max=qd_max, qdd_max=qdd_max), 10.0)
    _, sp_plain = run_free(robot, plain, 400)
    gen, sp = run_free(robot, limited, 700)
    q = np.array([Q0] + [p.q_des for p in sp])
    qd = np.diff(q, axis=0) / TS
    fast_plain = np.max(np.abs(np.diff(np.array([Q0] + [p.q_des for p in sp_plain]), axis=0) / TS))
    assert fast_plain > 1.2 * qd_max[0]                     # without the projection a joint runs too fast
    # the limit holds at the start of every tick; within the tick h' drifts by at most |h''| ds, so
    # the tick's mean joint speed may exceed it by |h''| sd_max^2 T (h'' bounded over the path)
    d = m.createData()
    ddh_max = max(np.abs(joint_derivatives(m, d, fid, p.q_des, *limited.path.derivatives(p.s)[1:],
                                           *limited.path.angular_derivatives(p.s))[1]).max() for p in sp[::20])
    sd_max = max(p.sd_max for p in sp)
    assert np.all(np.abs(qd) <= qd_max + 2 * ddh_max * sd_max**2 * TS)
    # accelerations while moving (the patent has no braking at s = 1): the second difference spans
    # two ticks over which h' sdd + h'' sd^2 drifts by about 3 |h''| sd sdd T
    moving = np.array([p.s for p in sp])[1:] < 1.0
    qdd = np.diff(qd, axis=0) / TS
    sdd_max = max(p.sdd_max for p in sp)
    assert np.all(np.abs(qdd[moving]) <= qdd_max + 3 * ddh_max * sd_max * sdd_max * TS)
    assert sp[-1].s == 1.0


def test_cartesian_path_past_a_joint_limit_is_refused(ur5):
    robot, start = ur5
    m, fid = pin.Model(robot.model), robot.frame_id("tool0")
    end, path = turning_line(start)
    d = m.createData()
    q_end = solve_ik(m, fid, end, Q0, data=d, **tick_ik_options(1e-10))
    moving = int(np.argmax(np.abs(q_end - Q0)))
    upper = m.upperPositionLimit.copy()
    lower = m.lowerPositionLimit.copy()
    if q_end[moving] > Q0[moving]:                              # put a stop halfway along that joint's travel
        upper[moving] = 0.5 * (Q0[moving] + q_end[moving])
    else:
        lower[moving] = 0.5 * (Q0[moving] + q_end[moving])
    m.upperPositionLimit, m.lowerPositionLimit = upper, lower
    with pytest.raises(InputError, match=f"joint '{m.names[moving + 1]}' past its (upper|lower) limit at s = 0\\.[45]"):
        movelf(m, fid, Q0, end, MotionParams(0.25, 1.0, admittance=0.002), 10.0)


# ---- blending ----------------------------------------------------------------------------------
def test_blended_path_is_tangent_continuous_with_exact_derivatives(ur5):
    _, start = ur5
    path = corner_path(start)
    for b in path.breaks[1:-1]:                                 # across every line/arc junction
        (f0, d0, _), (f1, d1, _) = path.derivatives(b - 1e-12), path.derivatives(b + 1e-12)
        assert np.linalg.norm(f1 - f0) < 1e-9 and np.linalg.norm(d1 - d0) < 1e-8 * path.total
    h = 1e-6
    for s in np.linspace(0.01, 0.99, 57):
        if np.min(np.abs(path.breaks - s)) < 2 * h:
            continue
        (fm, dm, _), (fp, dp, _), (_, df, ddf) = path.derivatives(s - h), path.derivatives(s + h), path.derivatives(s)
        assert np.linalg.norm(df) == pytest.approx(path.total, rel=1e-12)   # arc-length parameter
        # central differences: h^2/6 |f'''| with |f'''| <= total^3/r^2 ~ 1e-2 here, rounding 1e-16/h
        assert np.allclose((fp - fm) / (2 * h), df, atol=1e-8)
        assert np.allclose((dp - dm) / (2 * h), ddf, atol=1e-6 * max(1.0, np.linalg.norm(ddf)))
    # the arc keeps its radius and stays inside the corner (away from the sharp polyline vertex)
    corner = start.translation + [0.08, 0, 0]
    assert min(np.linalg.norm(path.derivatives(s)[0] - corner) for s in np.linspace(0, 1, 400)) > 0.005
    with pytest.raises(InputError, match="too large at point 1"):
        corner_path(start, radius=0.5)


def test_generator_runs_through_a_blended_corner_without_stopping(ur5):
    robot, start = ur5
    m, fid = robot.model, robot.frame_id("tool0")
    path = corner_path(start)
    ins = movecf(m, fid, Q0, path, MotionParams(0.1, 0.5, admittance=1.0, blend=True), 10.0)
    gen, sp = run_free(robot, ins, 700)
    s = np.array([p.s for p in sp])
    sd = np.array([p.sd for p in sp])
    assert s[-1] == 1.0
    on_arcs = (s > path.breaks[1]) & (s < path.breaks[2])
    assert on_arcs.any() and np.min(sd[on_arcs]) * path.total > 0.05     # keeps moving through the corner
    d = m.createData()
    for p in sp[::10]:
        _, df, ddf = path.derivatives(p.s)
        assert np.linalg.norm(df * p.sd) <= 0.1 * RATIO_TOL
        pin.framesForwardKinematics(m, d, p.q_des)
        assert np.linalg.norm(d.oMf[fid].translation - path.derivatives(p.s)[0]) <= 1e-9   # on the path


# ---- orientation-rate limits ---------------------------------------------------------------------
def test_orientation_rate_limits_project_and_hold(ur5):
    robot, start = ur5
    m, fid = robot.model, robot.frame_id("tool0")
    end, line = turning_line(start)
    dw, ddw = line.angular_derivatives(0.3)
    sd_max, sdd_max = project_limits(*line.derivatives(0.3)[1:], 0.25, 1.0, 0.9, dw=dw, ddw=ddw, w_max=0.2, dw_max=0.5)
    assert np.linalg.norm(dw) * sd_max == pytest.approx(0.2, rel=1e-12)     # the orientation limit is the active one
    assert np.linalg.norm(dw) * sdd_max <= 0.5 * RATIO_TOL
    ins = movelf(m, fid, Q0, end, MotionParams(0.25, 1.0, admittance=1.0, w_max=0.2, dw_max=0.5), 10.0)
    gen, sp = run_free(robot, ins, 900)
    d = m.createData()
    rotations = []
    for p in [None] + sp:
        pin.framesForwardKinematics(m, d, Q0 if p is None else p.q_des)
        rotations.append(d.oMf[fid].rotation.copy())
    rate = [np.linalg.norm(pin.log3(a.T @ b)) / TS for a, b in zip(rotations[:-1], rotations[1:])]
    assert max(rate) <= 0.2 * (1 + 1e-6)                         # measured on the IK output
    assert max(rate) > 0.19                                      # and reached: the limit is active
    angle = np.linalg.norm(line.angular_rate())
    t_end = (np.argmax([p.s >= 1.0 for p in sp]) + 1) * TS
    assert t_end >= angle / 0.2                                  # no faster than the rate limit allows
    with pytest.raises(InputError, match="w_max"):
        MotionParams(0.25, 1.0, admittance=1.0, w_max=0.2).validate()
