"""Spec seed-004 tests L1-L4: paths, their derivatives, and limits projected onto s."""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.dynamics.instructions import MotionParams, movejf, movelf
from robocal.dynamics.instructions import tick_ik_options
from robocal.model.inverse_kinematics import IKFailure, solve_ik
from robocal.dynamics.limits import project_limits
from robocal.dynamics.path import CircularPath, JointPath, LinearPath, SplinePath
from robocal.errors import InputError

RATIO_TOL = 1 + 1e-12


@pytest.fixture(scope="module")
def ur5():
    return robocal.load_example("ur5")


def random_path(rng):
    kind = rng.integers(3)
    if kind == 0:   # circle
        return CircularPath(rng.normal(size=3), rng.uniform(0.01, 1.0), rng.normal(size=3), rng.normal(size=3),
                            rng.uniform(0.1, 2 * np.pi))
    if kind == 1:   # helix
        return CircularPath(rng.normal(size=3), rng.uniform(0.01, 1.0), rng.normal(size=3), rng.normal(size=3),
                            rng.uniform(0.1, 4 * np.pi), pitch=rng.uniform(-0.1, 0.1))
    return SplinePath(np.cumsum(rng.normal(scale=0.2, size=(rng.integers(3, 8), 3)), axis=0))


def test_L1_limits_hold_on_random_curves():
    rng = np.random.default_rng(11)
    worst = 0.0
    for _ in range(3000):
        path = random_path(rng)
        s = rng.uniform()
        _, df, ddf = path.derivatives(s)
        v_max, a_max, c = rng.uniform(0.05, 2.0), rng.uniform(0.1, 10.0), rng.uniform(0.05, 0.99)
        sd_max, sdd_max = project_limits(df, ddf, v_max, a_max, c)
        assert sdd_max > 0
        for sd, sdd in ((sd_max, sdd_max), (-sd_max, -sdd_max), (sd_max, -sdd_max),
                        (rng.uniform(-1, 1) * sd_max, rng.uniform(-1, 1) * sdd_max)):
            v = np.linalg.norm(df * sd)
            a = np.linalg.norm(df * sdd + ddf * sd**2)
            worst = max(worst, v / v_max, a / a_max)
    assert worst <= RATIO_TOL


def test_path_derivatives_match_finite_differences(ur5):
    rng = np.random.default_rng(12)
    h = 1e-5
    paths = [random_path(rng) for _ in range(6)]
    fid = ur5.frame_id("tool0")
    paths.append(JointPath(ur5.model, fid, rng.uniform(-2, 2, 6), rng.uniform(-2, 2, 6)))
    for path in paths:
        for s in (0.13, 0.41, 0.87):        # off the spline knots i/(k-1), where f''' jumps
            f_m, df_m, _ = path.derivatives(s - h)
            f_p, df_p, _ = path.derivatives(s + h)
            _, df, ddf = path.derivatives(s)
            scale = max(1.0, np.linalg.norm(df), np.linalg.norm(ddf))
            # central differences: error ~ h^2 |f'''|/6 plus rounding 1e-16/h
            assert np.allclose((f_p - f_m) / (2 * h), df, atol=1e-7 * scale)
            assert np.allclose((df_p - df_m) / (2 * h), ddf, atol=1e-6 * scale)


def test_L2_straight_line_limits_exact():
    start = pin.SE3(np.eye(3), np.array([0.3, 0.1, 0.2]))
    end = pin.SE3(pin.rpy.rpyToMatrix(0.1, 0.2, 0.3), np.array([0.5, -0.1, 0.3]))
    line = LinearPath(start, end)
    for s in (0.0, 0.4, 1.0):
        _, df, ddf = line.derivatives(s)
        assert np.all(ddf == 0)
        sd_max, sdd_max = project_limits(df, ddf, 0.25, 1.0, 0.9)
        assert sd_max == pytest.approx(0.25 / line.length, rel=1e-15)
        assert sdd_max == pytest.approx(1.0 / line.length, rel=1e-15)
    assert np.allclose(line.pose(1.0).homogeneous, end.homogeneous, atol=1e-14)


def test_L3_joint_path_per_axis_limits(ur5):
    rng = np.random.default_rng(13)
    fid = ur5.frame_id("tool0")
    q0, q1 = rng.uniform(-2, 2, 6), rng.uniform(-2, 2, 6)
    path = JointPath(ur5.model, fid, q0, q1)
    qd_max, qdd_max = np.array([2.0, 2, 2, 3, 3, 3]), np.array([5.0, 5, 5, 8, 8, 8])
    for s in np.linspace(0, 1, 11):
        h, dh, ddh = path.joint_derivatives(s)
        assert np.allclose(dh, q1 - q0, atol=1e-15) and np.all(ddh == 0)
        assert np.allclose(h, q0 + s * (q1 - q0), atol=1e-15)
        _, df, ddf = path.derivatives(s)
        sd_max, sdd_max = project_limits(df, ddf, 0.5, 2.0, 0.9, dh, ddh, qd_max, qdd_max)
        for sd, sdd in ((sd_max, sdd_max), (-sd_max, sdd_max)):
            assert np.all(np.abs(dh * sd) <= qd_max * RATIO_TOL)
            assert np.all(np.abs(dh * sdd + ddh * sd**2) <= qdd_max * RATIO_TOL)
            assert np.linalg.norm(df * sd) <= 0.5 * RATIO_TOL
            assert np.linalg.norm(df * sdd + ddf * sd**2) <= 2.0 * RATIO_TOL


def test_L4_bad_instructions_rejected(ur5):
    fid = ur5.frame_id("tool0")
    q0 = np.array([0.3, -1.2, 1.5, -1.9, -1.5, 0.2])
    data = ur5.model.createData()
    pin.framesForwardKinematics(ur5.model, data, q0)
    here = data.oMf[fid].copy()
    ok = MotionParams(v_max=0.25, a_max=1.0, admittance=0.002)
    with pytest.raises(InputError, match="degenerate"):
        movelf(ur5.model, fid, q0, here, ok, 10.0)                   # x0 == x1
    with pytest.raises(InputError, match="degenerate"):
        movelf(ur5.model, fid, q0, pin.SE3(pin.rpy.rpyToMatrix(0, 0, 1) @ here.rotation, here.translation),
               ok, 10.0)                                             # pure reorientation
    with pytest.raises(InputError, match="degenerate"):
        movejf(ur5.model, fid, q0, q0.copy(), ok, 10.0)
    for bad in (dict(c=1.0), dict(c=0.0), dict(v_max=0.0), dict(v_max=-1.0), dict(a_max=0.0)):
        kw = dict(v_max=0.25, a_max=1.0, admittance=0.002) | bad
        with pytest.raises(InputError):
            movelf(ur5.model, fid, q0, pin.SE3(here.rotation, here.translation + [0.1, 0, 0]),
                   MotionParams(**kw), 10.0)
    with pytest.raises(InputError, match="finite"):
        movelf(ur5.model, fid, q0, pin.SE3(here.rotation, here.translation + [0.1, 0, 0]), ok, np.nan)
    with pytest.raises(InputError, match="not reachable"):
        movelf(ur5.model, fid, q0, pin.SE3(here.rotation, here.translation + [3.0, 0, 0]), ok, 10.0)
    with pytest.raises(InputError):
        project_limits(np.zeros(3), np.zeros(3), 1.0, 1.0, 0.5)


def test_ik_round_trip(ur5):
    rng = np.random.default_rng(14)
    fid = ur5.frame_id("tool0")
    m, d = ur5.model, ur5.model.createData()
    for _ in range(20):
        q = rng.uniform(-2, 2, 6)
        pin.framesForwardKinematics(m, d, q)
        target = d.oMf[fid].copy()
        q_sol = solve_ik(m, fid, target, q + rng.normal(scale=0.05, size=6), data=d, **tick_ik_options(1e-10))
        pin.framesForwardKinematics(m, d, q_sol)
        assert np.linalg.norm(pin.log6(target.actInv(d.oMf[fid])).vector) <= 1e-10
    with pytest.raises(IKFailure):
        solve_ik(m, fid, pin.SE3(np.eye(3), np.array([5.0, 0, 0])), q, data=d, **tick_ik_options(1e-10))
