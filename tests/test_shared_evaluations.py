"""The work calibrate() shares across its stages (issue 37): an evaluation taken with more parameters free serves
a stage that frees fewer, prior rows are added to an evaluation instead of evaluating again, the registration's
passes serve the default prior, and parameters hidden at the start are re-examined from the solver's own passes.
Each shortcut must give what evaluating afresh gives: the residuals do not depend on which parameters are free,
nor a Jacobian column on the other columns, so the comparisons are exact up to a few ulps."""
import numpy as np
import pytest

import robocal.estimation.calibrate as calibrate_module
from robocal import load_example
from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.identifiability import select_base_parameters
from robocal.estimation.problem import Problem
from robocal.estimation.registration import (apply_default_prior, data_rows, evaluate_with_free, register_nominal,
                                             subset_evaluation, with_current_priors)
from robocal.estimation.physical_scale import physical_scales
from robocal.estimation.solve import triangle
from robocal.model.parameters import robot_parameters
from robocal.residuals import PointResidual
from robocal.workflows.evaluate import setup_for_data
from synthetic_cases import ur5_pose_problem
from validation_cases import write_case

WEAK = {"wrist_2_joint": 0.02, "wrist_3_joint": 0.02}    # two wrist joints barely move: weak directions
TOL = 1e-13     # relative: the same formulas on the same values, at most a different order of sums


def _close(a, b):
    scale = max(np.abs(b).max(), 1e-300) if np.size(b) else 1.0
    return np.abs(a - b).max() / scale < TOL if np.size(b) else np.size(a) == 0


def _posed_problem(rng, n=25):
    problem = ur5_pose_problem(rng, n)
    simulate_measurements(problem, perturb(problem.params, rng), rng)
    problem.params = problem.params.copy()
    for name, sigma in (("base.tx", 0.01), ("elbow_joint.offset", 1e-3), ("tool0.rz", 2e-3)):   # user priors
        problem.params[name].prior_sigma, problem.params[name].prior_mean = sigma, 0.001
    return problem


def test_a_subset_of_an_evaluation_is_the_evaluation_with_that_subset_free():
    problem = _posed_problem(np.random.default_rng(2))
    params = problem.params
    free = params.free_names
    whole = problem.evaluate()
    names = [n for n in free if n.startswith(("base.", "tool0."))]      # priors on some of them, not all
    sub = subset_evaluation(problem, whole, names)
    for n in free:
        params[n].vary = n in names
    alone = problem.evaluate()
    assert sub.J.shape == alone.J.shape == (len(alone.r), len(names))
    assert _close(sub.r, alone.r) and _close(sub.J, alone.J) and _close(sub.raw, alone.raw)
    assert np.array_equal(sub.group, alone.group)
    # the same from the subset's side: `free` names the columns the evaluation was taken with
    assert _close(subset_evaluation(problem, whole, names, free).J, alone.J)


def test_prior_rows_added_to_an_evaluation_are_those_of_evaluating_again():
    problem = _posed_problem(np.random.default_rng(3))
    before = problem.evaluate()
    for name in ("shoulder_lift_joint.ty", "wrist_1_joint.offset"):      # priors added after the evaluation
        problem.params[name].prior_sigma, problem.params[name].prior_mean = 5e-4, -0.002
    added = with_current_priors(problem, before)
    again = problem.evaluate()
    assert _close(added.r, again.r) and _close(added.J, again.J) and np.array_equal(added.group, again.group)


def test_evaluating_with_more_parameters_free_restores_the_flags_and_the_rows():
    problem = _posed_problem(np.random.default_rng(4))
    params = problem.params
    requested = params.free_names
    for n in requested[:10]:
        params[n].vary = False
    blocks = [(b.name, b.rows) for b in problem.layout()]
    ev = evaluate_with_free(problem, problem.evaluate, requested)
    assert ev.J.shape[1] == len(requested)
    assert [params[n].vary for n in requested] == [False] * 10 + [True] * (len(requested) - 10)
    assert [(b.name, b.rows) for b in problem.blocks] == blocks


def test_the_registration_s_last_pass_gives_the_default_prior_of_a_fresh_evaluation(tmp_path):
    """Two wrist joints barely moving (validation_cases): the data leave parameters loose and the default prior
    is applied; taken from the registration's passes or from a fresh evaluation at the registered frames, the
    same prior."""
    cfg, _, _ = write_case(tmp_path, np.random.default_rng(1), n=30, spread=WEAK)
    priors = []
    for wide in (False, True):
        setup = setup_for_data(cfg)
        problem, options = setup.problem, setup.options
        registered = register_nominal(problem, options, problem.evaluate(), wide=wide)
        assert (registered.evaluation is not None) == wide and registered.success
        prior = apply_default_prior(problem, registered, physical_scales(problem), options.rank_rtol)
        priors.append((registered.values, prior, {p.name: p.prior_sigma for p in problem.params}))
    (values_a, prior_a, sigmas_a), (values_b, prior_b, sigmas_b) = priors
    assert prior_a.applied and prior_b.applied
    assert values_a == values_b and sigmas_a == sigmas_b
    assert prior_a.strength == prior_b.strength and prior_a.noise_ratio == pytest.approx(prior_b.noise_ratio,
                                                                                          rel=TOL)


def _marker_on_the_last_axis(rng, n=30):
    """A point marker guessed at the flange's origin, on wrist 3's axis: that joint's offset has no effect at the
    start, and at the solution it is confounded with the marker (a turn of the flange moves the marker)."""
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "offsets", base=True)
    res = PointResidual("marker", "tool0", np.arange(n), np.zeros((n, 3)), point_unknown=True, sigma=5e-5)
    problem = Problem(robot, params, joints, random_configurations(robot, joints, n, rng), [res])
    truth = perturb(problem.params, rng)
    for axis, v in zip("xyz", (0.05, 0.03, 0.08)):
        truth[f"marker.point.{axis}"].value = v
    simulate_measurements(problem, truth, rng)
    return problem


def test_hidden_parameters_are_judged_at_the_solution_as_a_fresh_evaluation_judges_them(monkeypatch):
    problem = _marker_on_the_last_axis(np.random.default_rng(3))
    requested = problem.params.free_names
    # passes outside the solvers' own evaluations: only the start (the check at the solution reuses the
    # solver's last pass, taken with every requested column)
    outside, in_solver = [], [False]
    evaluate, solver = Problem.evaluate, calibrate_module.levenberg_marquardt

    def counted(self, jacobian=True):
        if not in_solver[0]:
            outside.append(1)
        return evaluate(self, jacobian)

    def solver_counted(fun, *args, **kwargs):
        def fun_counted(x):
            in_solver[0] = True
            try:
                return fun(x)
            finally:
                in_solver[0] = False
        return solver(fun_counted, *args, **kwargs)

    monkeypatch.setattr(Problem, "evaluate", counted)
    monkeypatch.setattr(calibrate_module, "levenberg_marquardt", solver_counted)
    result = calibrate(problem, CalibrationOptions(regularisation="none", register_before=False))
    monkeypatch.undo()
    assert result.success and "wrist_3_joint.offset" in [requested[j] for j in result.selection.dependent]
    assert len(outside) == 1
    # a fresh evaluation at the solution, every requested parameter free, judged with the same rule
    kept = problem.params.free_names
    for n in requested:
        problem.params[n].vary = True
    ev = problem.evaluate()
    T = triangle(ev.J, ev.r, None, len(requested), data_rows(problem, len(ev.r)))
    allowed = {requested.index(n) for n in kept} | {requested.index("wrist_3_joint.offset")}
    fresh = select_base_parameters(T[:-1, :-1], requested, 1e-8, allowed)
    assert fresh.independent == result.selection.independent
    np.testing.assert_allclose(result.selection.regrouping, fresh.regrouping, rtol=1e-9, atol=1e-12)


def test_the_widening_threshold_leaves_large_problems_alone():
    assert calibrate_module.WIDE_REGISTRATION < 6 * 10000 * 54      # a 10000-pose UR5 keeps narrow passes
