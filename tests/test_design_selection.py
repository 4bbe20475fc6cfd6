"""Pose selection on UR5 (6D tracker, full placement parameters): quality, determinism, exchange optimality,
and unidentifiable pose sets reported by name."""
import numpy as np
import pytest

from robocal.design.selection import DesignMatrix, assess, select_poses
from robocal.design.candidates import random_candidates
from robocal.errors import InputError
from robocal.design.prediction import pose_jacobians, predict_parameters, predict_pose_accuracy
from synthetic_cases import ur5_pose_problem


def candidate_problem(seed, n):
    problem = ur5_pose_problem(np.random.default_rng(seed), 1)
    problem_n = ur5_pose_problem(np.random.default_rng(seed), n)
    problem_n.values = random_candidates(problem.robot, problem.joint_names, n, np.random.default_rng(seed))
    return problem_n


@pytest.fixture(scope="module")
def ur5():
    problem = candidate_problem(11, 300)
    design = DesignMatrix.from_problem(problem)
    validation = random_candidates(problem.robot, problem.joint_names, 100, np.random.default_rng(12))
    return problem, design, pose_jacobians(problem, "tool0", validation)


def test_base_columns_are_the_ur5_base_set(ur5):
    _, design, _ = ur5
    assert design.n_candidates == 300
    assert len(design.base_names) == 30          # 4R + 2P per revolute joint + 6 for a 6D measurement


def test_d_optimal_beats_the_median_random_set(ur5):
    _, design, G = ur5
    sel = select_poses(design, 30, "D")
    assert sel.identifiability.ok
    d_opt = predict_pose_accuracy(predict_parameters(design, sel.chosen), G).mean_position
    rng = np.random.default_rng(13)
    random_sets = [predict_pose_accuracy(predict_parameters(design, rng.choice(300, 30, replace=False)), G)
                   .mean_position for _ in range(100)]
    assert d_opt < np.median(random_sets)
    # and it is D-better than every random set (log det; what it was asked to maximise)
    best_random = max(design.criteria(rng.choice(300, 30, replace=False))["D"] for _ in range(100))
    assert sel.values["D"] > best_random


@pytest.mark.parametrize("criterion", ["D", "E", "O1", "O2", "O4", "O5", "A"])
def test_same_selection_on_every_run(criterion):
    a = DesignMatrix.from_problem(candidate_problem(21, 80))
    b = DesignMatrix.from_problem(candidate_problem(21, 80))
    sa, sb = select_poses(a, 12, criterion), select_poses(b, 12, criterion)
    np.testing.assert_array_equal(sa.chosen, sb.chosen)
    assert sa.value == sb.value


@pytest.mark.parametrize("criterion", ["D", "O4"])
def test_exchange_ends_where_no_single_swap_helps(criterion):
    design = DesignMatrix.from_problem(candidate_problem(31, 40))
    sel = select_poses(design, 8, criterion)
    assert sel.value >= sel.greedy_value
    chosen = list(sel.chosen)
    for pos in range(len(chosen)):
        for k in range(design.n_candidates):
            if k in chosen:
                continue
            trial = chosen.copy()
            trial[pos] = k
            assert design.criteria(trial)[criterion] <= sel.value * (1 + 1e-8) + 1e-12


def test_too_few_poses_reported_with_the_parameters_they_leave_open(ur5):
    _, design, G = ur5
    sel = select_poses(design, 4, "D")          # 24 rows for 30 base parameters
    ident = sel.identifiability
    assert not ident.ok and len(ident.unidentifiable) == 6
    assert set(ident.unidentifiable) <= set(design.base_names)
    assert all(line.startswith(name) for line, name in zip(ident.explanation, ident.unidentifiable))
    pred = predict_parameters(design, sel.chosen)
    assert pred.unidentifiable == ident.unidentifiable and np.all(np.isinf(pred.stderr))
    assert np.all(np.isinf(predict_pose_accuracy(pred, G).position))


def test_a_wrist_that_never_turns_leaves_the_tool_frame_open():
    problem = candidate_problem(41, 60)
    problem.values[:30, 5] = 0.3                 # wrist_3 at one angle in the first 30 candidates
    design = DesignMatrix.from_problem(problem)
    assert assess(design, np.arange(60)).ok      # all candidates: the full base set
    ident = assess(design, np.arange(30))
    # With the last joint never turning, the tool frame cannot be told from the placement of that joint
    # (about and along the axes normal to it): the later-declared tool0 components are named as lost.
    assert ident.unidentifiable == ["tool0.tx", "tool0.ty", "tool0.rx", "tool0.ry"]
    assert all("wrist_3_joint." in line for line in ident.explanation)


@pytest.mark.parametrize("criterion", ["D", "O1"])
def test_any_jacobian_source_quadratic_regression_has_the_textbook_optimum(criterion):
    """y = a + b x + c x^2 on x in [-1, 1]: the D-optimal 3-point design is {-1, 0, 1} (Kiefer); O1 is a
    monotone function of det for a fixed row count, so it must agree."""
    x = np.linspace(-1, 1, 21)
    J = np.column_stack([np.ones_like(x), x, x ** 2])
    design = DesignMatrix.from_rows(J, ["a", "b", "c"], [[i] for i in range(21)])
    sel = select_poses(design, 3, criterion)
    np.testing.assert_allclose(np.sort(x[sel.chosen]), [-1, 0, 1], atol=1e-12)


def test_bad_requests_raise_input_errors(ur5):
    _, design, _ = ur5
    with pytest.raises(InputError, match="unknown criterion"):
        select_poses(design, 10, "Z")
    with pytest.raises(InputError, match="cannot choose 400 poses from 300"):
        select_poses(design, 400)
    with pytest.raises(InputError, match="needs validation configurations"):
        select_poses(design, 10, "I")


def test_closed_chain_stewart_platform_plans_with_the_same_calls():
    from pathlib import Path

    from robocal.systems.stewart import mechanism as st
    from robocal.model.parameters import placement_parameters, robot_parameters
    from robocal.estimation.problem import Problem
    from robocal.residuals import PoseResidual
    from robocal.model.robot import load_urdf

    robot = load_urdf(Path(__file__).resolve().parents[1] / "urdf" / "stewart_6_6.urdf")
    act = list(robot.loops.actuated)
    geometry = st.geometry_from_model(robot)
    rng = np.random.default_rng(0)
    readings = st.inverse_kinematics_batch(geometry, *st.random_workspace_poses(geometry, 120, rng))
    # the 42 parameters of spec seed-000 (N_j, T_j, o_j) plus the tracker frame
    params = robot_parameters(robot, act, "offsets", base=True,
                              frames={f"leg{j}_top.link2": ("tx", "ty", "tz") for j in range(1, 7)})
    for j in range(1, 7):
        for p in placement_parameters("joint_placement", f"leg{j}_u1", ("tx", "ty", "tz")):
            params.add(p)
    n = len(readings)
    tracker = PoseResidual("tracker", "tool", np.arange(n), np.tile([0, 0, 0, 0, 0, 0, 1.0], (n, 1)),
                           sigma=(1e-5, 1e-5))
    problem = Problem(robot, params, act, readings, [tracker])
    design = DesignMatrix.from_problem(problem)
    # the tracker frame absorbs 6 of the base-joint coordinates; the other 42 are identifiable
    assert len(design.base_names) == 42 and len(design.base.dependent) == 6
    G = pose_jacobians(problem, "tool", readings[:40])
    sel = select_poses(design, 20, "D")
    assert sel.identifiability.ok
    d_opt = predict_pose_accuracy(predict_parameters(design, sel.chosen), G).mean_position
    random_sets = [predict_pose_accuracy(predict_parameters(design, rng.choice(n, 20, replace=False)), G)
                   .mean_position for _ in range(30)]
    assert d_opt < np.median(random_sets)


@pytest.mark.parametrize("criterion", ["D", "A", "E", "O5"])
def test_tall_blocks_select_as_their_full_rows_would(criterion):
    """A candidate with more rows than columns (a camera image) is kept as the R of its QR: the same information
    matrices, so the same choice as with the full rows and the same criterion values to rounding."""
    rng = np.random.default_rng(3)
    K, d, L = 40, 12, 5
    J = rng.normal(size=(K * d, L)) * rng.uniform(0.1, 3.0, (K, 1)).repeat(d, axis=0)
    units = [np.arange(k * d, (k + 1) * d) for k in range(K)]
    design = DesignMatrix.from_rows(J, [f"p{i}" for i in range(L)], units)
    assert design.blocks.shape == (K, L, L)
    full = DesignMatrix.from_rows(J, [f"p{i}" for i in range(L)], units)
    full.blocks = np.stack([J[u] / full.scale for u in units])
    chosen = [0, 5, 7, 9]
    assert np.allclose(design.information(chosen), full.information(chosen), rtol=1e-12, atol=1e-12)
    a, b = select_poses(design, 8, criterion), select_poses(full, 8, criterion)
    assert list(a.chosen) == list(b.chosen)
    assert a.value == pytest.approx(b.value, rel=1e-9)


@pytest.mark.parametrize("criterion", ["D", "E"])
def test_one_greedy_order_serves_every_count(ur5, criterion):
    """select_poses from a prefix of one greedy run is select_poses itself (the accuracy curve's shortcut)."""
    from robocal.design.selection import greedy_order
    _, design, _ = ur5
    order = greedy_order(design, 40, criterion)
    for n in (12, 30, 40):
        plain, shared = select_poses(design, n, criterion), select_poses(design, n, criterion, start=order[:n])
        assert plain.chosen.tolist() == shared.chosen.tolist() and plain.greedy_value == shared.greedy_value
        assert plain.value == shared.value
