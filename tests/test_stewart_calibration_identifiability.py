"""The identifiability findings of spec seed-000 §6.5 (tests 7.1, 8, 9, 10, 12) and §6.6: null-space
dimensions at the spec's threshold (1e-10 relative singular value) and the report's words for them."""
import numpy as np
import pytest

from robocal.estimation.calibrate import calibrate
from robocal.estimation.problem import Problem
from robocal.systems.stewart import calibration as sc
from robocal.systems.stewart import modes as sm
from test_stewart_calibration_recovery import TOOL, contact_data, robot, truth_params  # noqa: F401 (fixture)

ANGLES = np.radians([15, 7.5, 0, -7.5, -15])


def jig_problem(robot, n, rng, tilted, with_c, fix_t):
    truth = truth_params(rng, fix_t=fix_t)
    tips = sc.random_tips(n, rng)
    abc = np.zeros((n, 3))
    if tilted:
        abc[:, :2] = rng.choice(ANGLES, (n, 2))
    R = np.array([sm.rotation(a) for a in abc])
    s = sc.struts(sc.geometry(robot, truth), sc.tip_to_platform(tips, R, TOOL))
    params = at_truth(sc.stewart_parameters(fix_platform_joints=fix_t), truth)
    u = [1, 1, 1, 1000, 1000, 1000 if with_c else 0]
    return params, Problem(robot, params, sc.actuated(robot), s,
                           sm.pose_residuals("jig", robot, np.arange(n), np.column_stack([tips, abc]), u, TOOL,
                                             (1e-6, 1e-6)))


def at_truth(params, truth):
    """Identifiability of a data design is a property of the linearisation at the true machine
    (the spec's table): evaluated elsewhere, a flat jig's poses are not exactly flat for the model."""
    for p in truth:
        params[p.name].value = p.value
    return params


def null_dim(problem):
    return sc.null_directions(problem.evaluate().J, 1e-10)[0].shape[1]


@pytest.mark.parametrize("tilted, with_c, fix_t, rank, n_free", [
    (False, True, False, 24, 42), (False, True, True, 24, 24), (False, False, True, 23, 24),
    (True, False, False, 41, 42), (True, True, False, 42, 42)])
def test_flat_and_tilted_jig(robot, tilted, with_c, fix_t, rank, n_free):
    params, problem = jig_problem(robot, 12, np.random.default_rng(10), tilted, with_c, fix_t)
    assert len(params.free_names) == n_free
    assert n_free - null_dim(problem) == rank
    words = sc.explain(problem.evaluate().J, robot, params, TOOL)
    if not tilted and not fix_t:
        assert sum("together with platform joint" in w for w in words) == 18
    if tilted and not with_c:
        assert any("spinning the platform joints T about the tool axis" in w for w in words)
        # the core's report agrees: one parameter is fixed and named
        assert sc.identifiability(problem).rank == 41


def test_without_c_garbage_c_values_do_not_change_the_fit(robot):
    fits = []
    for garbage in (0.0, 0.3):
        rng = np.random.default_rng(71)
        truth = truth_params(rng)
        tips = sc.random_tips(12, rng)
        abc = np.radians(rng.uniform(-15, 15, (12, 3)))
        R = np.array([sm.rotation(a) for a in abc])
        s = sc.struts(sc.geometry(robot, truth), sc.tip_to_platform(tips, R, TOOL))
        abc[:, 2] += garbage * rng.normal(size=12)        # C not measured: any value
        params = sc.stewart_parameters()
        result = calibrate(Problem(robot, params, sc.actuated(robot), s,
                                   sm.pose_residuals("p", robot, np.arange(12), np.column_stack([tips, abc]),
                                                     [1, 1, 1, 1000, 1000, 0], TOOL, (1e-6, 1e-6))))
        assert result.selection.rank == 41 and len(result.unidentifiable) == 1
        assert np.all(np.isfinite(params.free_values()))
        fits.append(params.free_values())
    assert np.array_equal(fits[0], fits[1])


def contact_problem(robot, rng, kinds, fix_t=True, bars=3):
    truth = truth_params(rng, fix_t=fix_t)
    blocks, s = contact_data(robot, truth, rng, ball_bar_locations=bars, per_bar=30)
    keep = [b for b in blocks if b.name.rstrip("0123456789") in kinds]
    idx = np.concatenate([b.samples for b in keep])
    remap = {int(i): k for k, i in enumerate(idx)}
    for b in keep:
        b.samples = np.array([remap[int(i)] for i in b.samples])
    params = at_truth(sc.stewart_parameters(fix_platform_joints=fix_t), truth)
    return params, Problem(robot, params, sc.actuated(robot), s[idx], keep)


@pytest.mark.parametrize("bars, expected", [(1, 3), (2, 1), (3, 0)])
def test_ball_bar_locations(robot, bars, expected):
    params, problem = contact_problem(robot, np.random.default_rng(80 + bars), ("dbb",), bars=bars)
    assert null_dim(problem) == expected
    if bars == 1:
        words = sc.explain(problem.evaluate().J, robot, params, TOOL, centres=[(0, 0, 0.22)])
        assert sum("about centre 1" in w for w in words) == 3


@pytest.mark.parametrize("planes, expected", [(1, 3), (2, 1), (3, 0)])
def test_reference_planes(robot, planes, expected):
    params, problem = contact_problem(robot, np.random.default_rng(90 + planes), ("plane",))
    keep = problem.residuals[:planes]
    n = sum(len(b.samples) for b in keep)
    problem = Problem(robot, params, sc.actuated(robot), problem.values[:n], keep)
    assert null_dim(problem) == expected


def test_point_only_data_cannot_see_the_platform_joints_rotating_about_the_tip(robot):
    params, problem = contact_problem(robot, np.random.default_rng(9), ("dbb",), fix_t=False)
    assert null_dim(problem) >= 3
    words = sc.explain(problem.evaluate().J, robot, params, TOOL)
    assert any("rotating the platform joints T about the tool tip" in w for w in words)


def test_variant_h_one_ball_bar_with_unknown_centre_needs_one_full_pose(robot):
    """Spec test 12: one DBB location with unknown centre and offset, T fixed (24 + 4 = 28 unknowns):
    rank 22 alone, 28 once a single full pose is added."""
    rng = np.random.default_rng(12)
    truth = truth_params(rng, fix_t=True)
    geo = sc.geometry(robot, truth)
    c, off, n = np.array([0.0, 0.0, 0.22]), 0.0123, 30
    length = rng.uniform(0.09, 0.11, n)
    tips_bar = sc.sphere_tips(c, length, n, rng)
    _, R_bar = sc.random_orientations(n, rng)
    s_bar = sc.struts(geo, sc.tip_to_platform(tips_bar, R_bar, TOOL))
    tip1 = sc.random_tips(1, rng)
    abc1, R1 = sc.random_orientations(1, rng)
    s1 = sc.struts(geo, sc.tip_to_platform(tip1, R1, TOOL))

    def rank(with_pose):
        params = at_truth(sc.stewart_parameters(fix_platform_joints=True), truth)
        blocks = [sm.ball_bar_residual("dbb", np.arange(n), length - off, c, TOOL, centre_unknown=True)]
        values = s_bar
        if with_pose:
            blocks += sm.pose_residuals("pose", robot, [n], np.column_stack([tip1, abc1]),
                                        [1, 1, 1, 1, 1, 1], TOOL, (1e-6, 1e-6))
            values = np.vstack([s_bar, s1])
        problem = Problem(robot, params, sc.actuated(robot), values, blocks)
        for name, v in (("dbb.centre.x", c[0]), ("dbb.centre.y", c[1]), ("dbb.centre.z", c[2]), ("dbb.offset", off)):
            params[name].value = v                       # the linearisation at the true set-up as well
        assert len(params.free_names) == 28
        return 28 - null_dim(problem)

    assert rank(False) == 22
    assert rank(True) == 28


def test_three_ball_bars_and_tilt_only_poses_leave_only_the_spin(robot):
    """Spec test 9, second half: 3 DBB locations + 10 poses measuring only A and B (u = 0,0,0,1,1,0),
    all 42 parameters free: one null direction remains, the spin of T about the tool axis."""
    rng = np.random.default_rng(19)
    truth = truth_params(rng)
    blocks, s = contact_data(robot, truth, rng, ball_bar_locations=3, per_bar=30)
    keep = [b for b in blocks if b.name.startswith("dbb")]
    idx = np.concatenate([b.samples for b in keep])
    remap = {int(i): k for k, i in enumerate(idx)}
    for b in keep:
        b.samples = np.array([remap[int(i)] for i in b.samples])
    n_bar = len(idx)
    tips = sc.random_tips(10, rng)
    abc, R = sc.random_orientations(10, rng)
    s_tilt = sc.struts(sc.geometry(robot, truth), sc.tip_to_platform(tips, R, TOOL))
    keep += sm.pose_residuals("tilt", robot, np.arange(n_bar, n_bar + 10), np.column_stack([tips, abc]),
                              [0, 0, 0, 1000, 1000, 0], TOOL, (1e-6, 1e-6))
    params = at_truth(sc.stewart_parameters(), truth)
    problem = Problem(robot, params, sc.actuated(robot), np.vstack([s[idx], s_tilt]), keep)
    for b in keep:                                   # the linearisation at the true set-up
        if b.name.startswith("dbb"):
            params[f"{b.name}.offset"].value = 0.0123
    assert null_dim(problem) == 1
