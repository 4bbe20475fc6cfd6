"""The batched evaluation (whole-array numpy over the samples) against the plain per-sample reference.

Both compute the same formulas in a different order, so they differ by rounding only: a few ulps of the
largest entry, amplified at most by the condition of log3 near the identity (the pose rows) to ~1e-14
relative. 1e-10 relative is the bar set for the batched path (robocal issue 20); a wrong sign, frame or
column shows up as O(1).
"""
import numpy as np
import pinocchio as pin
import pytest

from reference_evaluation import reference_evaluate
from test_residual_jacobians import free_auxiliaries
from robocal import load_example
from robocal.estimation.calibrate import calibrate
from robocal.estimation.problem import Problem
from robocal.model.batch_kinematics import supports_batch
from robocal.model.parameters import robot_parameters
from robocal.residuals import BallBarResidual, PlaneResidual, PointResidual, PoseResidual, SphereResidual
from robocal.design.simulate import simulate_measurements

RTOL = 1e-10


def _quaternions(rng, n):
    return np.array([pin.Quaternion(pin.exp3(rng.normal(0, 0.3, 3))).coeffs() for _ in range(n)])


def _problem(rng, load_kinds=("compliance", "backlash"), n=40):
    """UR5 with a tool frame; every geometric kind free plus the chosen load-dependent kinds; the five
    batched residual types, each on its own samples (a pose term and a point term share some)."""
    robot = load_example("ur5")
    robot.add_frame("tcp", "tool0", pin.SE3(pin.rpy.rpyToMatrix(0.1, -0.2, 0.3), np.array([0.01, 0.02, 0.1])))
    joints = robot.joint_names
    kinds = {k: True for k in load_kinds}
    params = robot_parameters(robot, joints, "full", frames={"tcp": True, "tool0": True}, base=True, **kinds)
    for p in params:   # away from zero so every exp6 Jacobian and load term matters
        p.value = rng.normal(0, 1e-3 if p.kind in ("joint_compliance", "joint_tilt") else 0.01)
    values = rng.uniform(-2, 2, (n, len(joints)))
    s = np.arange(n)
    residuals = [
        PoseResidual("tracker", "tcp", s[:15], np.hstack([rng.normal(0.5, 0.2, (15, 3)), _quaternions(rng, 15)])),
        PointResidual("marker", "tool0", s[10:22], rng.normal(0.4, 0.2, (12, 3)), point=(0.01, 0.02, 0.03),
                      point_unknown=True),
        PlaneResidual("table", "tcp", s[22:28], normal=(0.1, 0.2, 1.0), offset=0.3, point=(0, 0, 0.01),
                      point_unknown=True, tip_radius=0.003),
        SphereResidual("ball", "tcp", s[28:34], centre=(0.3, 0.2, 0.1), radius=0.0125, point=(0, 0.01, 0.01)),
        BallBarResidual("bar", "tcp", s[34:], rng.uniform(0.3, 0.5, n - 34), centre=(0.2, 0.3, 0.1), offset=0.15,
                        point=(0, 0, 0.02)),
    ]
    residuals[0].weights[5] = 0.0   # a dropped row keeps the row bookkeeping honest
    directions = rng.integers(-1, 2, values.shape).astype(float)
    problem = Problem(robot, params, joints, values, residuals, directions=directions)
    free_auxiliaries(params, rng)
    return problem


def _relative(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


@pytest.mark.parametrize("load_kinds", [("compliance", "backlash"), ("tilt",)])
def test_batched_residuals_and_jacobian_match_the_per_sample_reference(load_kinds):
    problem = _problem(np.random.default_rng(11), load_kinds)
    batched = supports_batch(problem.model_state())
    assert batched == ("tilt" not in load_kinds)     # tilts move placements per sample: per-sample path
    ev, ref = problem.evaluate(), reference_evaluate(problem)
    assert ev.J.shape == ref.J.shape and ev.J.shape[1] == len(problem.params.free_names)
    np.testing.assert_array_equal(ev.group, ref.group)
    assert _relative(ev.r, ref.r) < RTOL
    assert _relative(ev.raw, ref.raw) < RTOL
    for block in problem.blocks:   # per block, so a small block's error is not hidden by a large one
        assert _relative(ev.J[block.rows], ref.J[block.rows]) < RTOL, block.name
    no_jac = problem.evaluate(jacobian=False)
    assert no_jac.J is None and _relative(no_jac.r, ref.r) < RTOL
    # only a frame parameter changes: the kinematics kept from the last pass must not be reused as they are
    problem.params["tcp.rx"].value += 0.05
    assert _relative(problem.evaluate().J, reference_evaluate(problem).J) < RTOL


def test_kinematics_kept_between_passes_follow_every_parameter():
    """One residual, so the regressors kept from the last pass would be reused: a frame change alone keeps
    them, a joint placement or an offset must not."""
    full = _problem(np.random.default_rng(13))
    problem = Problem(full.robot, full.params, full.joint_names, full.values, full.residuals[:1],
                      directions=full.directions)
    problem.evaluate()
    for name, step in (("tcp.rx", 0.05), ("elbow_joint.tx", 0.01), ("wrist_2_joint.rz", 0.05),
                       ("shoulder_lift_joint.offset", 0.1), ("base.tz", 0.02)):
        problem.params[name].value += step
        ev, ref = problem.evaluate(), reference_evaluate(problem)
        assert _relative(ev.r, ref.r) < RTOL and _relative(ev.J, ref.J) < RTOL, name


def test_kept_kinematics_serve_another_parameter_structure(monkeypatch):
    """A registration (frames free, joints fixed) after a full pass at the same joint placements reuses the
    regressors: Pinocchio is not run again; a joint placement moved runs it."""
    full = _problem(np.random.default_rng(14))
    problem = Problem(full.robot, full.params, full.joint_names, full.values, full.residuals[:1],
                      directions=full.directions)
    calls = []
    regressor = pin.computeJointKinematicRegressor
    monkeypatch.setattr(pin, "computeJointKinematicRegressor", lambda *a: calls.append(1) or regressor(*a))
    problem.evaluate()
    first = len(calls)
    assert first == len(problem.residuals[0].samples)
    for p in problem.params:                 # the registration's structure: only frames and the base free
        if p.kind not in ("frame_placement", "base"):
            p.vary = False
    ev, ref = problem.evaluate(), reference_evaluate(problem)
    assert len(calls) == first and _relative(ev.J, ref.J) < RTOL
    problem.params["elbow_joint.tx"].value += 0.01
    ev, ref = problem.evaluate(), reference_evaluate(problem)
    assert len(calls) > first and _relative(ev.J, ref.J) < RTOL and _relative(ev.r, ref.r) < RTOL


def test_chunks_give_the_same_rows_as_one_pass():
    problem = _problem(np.random.default_rng(12))
    ev = problem.evaluate()
    for rows, r, raw, group, J in problem.pieces(chunk_terms=4):
        np.testing.assert_array_equal(group, ev.group[rows])
        assert np.abs(r - ev.r[rows]).max() <= 1e-14 * np.abs(ev.r).max()
        assert np.abs(J - ev.J[rows]).max() <= 1e-14 * np.abs(ev.J).max()


def test_a_subclass_that_overrides_evaluate_takes_the_per_term_path():
    class Scaled(PointResidual):
        def evaluate(self, k, states, aux):
            t = super().evaluate(k, states, aux)
            t.r = 2.0 * t.r
            return t

    rng = np.random.default_rng(3)
    res = Scaled("m", "tool0", np.arange(3), rng.normal(size=(3, 3)))
    assert not res.batched and PointResidual("p", "tool0", [0], np.zeros((1, 3))).batched
    robot = load_example("ur5")
    problem = Problem(robot, robot_parameters(robot, robot.joint_names, "offsets"), robot.joint_names,
                      rng.uniform(-2, 2, (3, 6)), [res])
    assert _relative(problem.evaluate().r, reference_evaluate(problem).r) < RTOL


def test_fitted_parameters_match_the_reference_fit():
    """Pose and point data simulated on a perturbed robot (with compliance and backlash), contact rows as
    drawn: both paths must reach the same least-squares solution."""
    rng = np.random.default_rng(5)
    problem = _problem(rng, n=60)
    problem.residuals[0].samples = np.arange(30)
    problem.residuals[0].set_measurements(np.tile([0, 0, 0, 0, 0, 0, 1.0], (30, 1)))
    problem.residuals[1].samples = np.arange(20, 45)
    problem.residuals[1].measurements = np.zeros((25, 3))
    problem.residuals = [problem.residuals[0], problem.residuals[1], problem.residuals[4]]
    problem.residuals[2].samples = np.arange(45, 60)
    problem.residuals[2].measurements = np.zeros((15, 1))
    truth = problem.params.copy()
    start = problem.params.copy()
    for p in start:
        if p.kind != "auxiliary":
            p.value = 0.0
    simulate_measurements(problem, truth, rng)
    fits = []
    for reference in (False, True):
        problem.params = start.copy()
        if reference:
            problem.evaluate = lambda jacobian=True: reference_evaluate(problem, jacobian)
        result = calibrate(problem)
        assert result.solve.success
        fits.append(np.array([problem.params[n].value for n in problem.params.names]))
    assert _relative(fits[0], fits[1]) < RTOL


def test_no_free_parameter_still_gives_residuals():
    problem = _problem(np.random.default_rng(4))
    problem.params.fix("*")
    ev = problem.evaluate()
    assert ev.J.shape == (len(ev.r), 0) and _relative(ev.r, reference_evaluate(problem).r) < RTOL


def test_unordered_and_repeated_samples_match_the_reference():
    """A block whose samples are not increasing (and repeat) takes the batched path through np.unique and
    back: its rows must still be the reference's."""
    rng = np.random.default_rng(5)
    problem = _problem(rng)
    samples = np.array([7, 3, 3, 12, 0, 7])
    problem.residuals.append(PointResidual("unordered", "tcp", samples, rng.normal(0.4, 0.2, (len(samples), 3)),
                                           point=(0.01, 0.0, 0.02)))
    problem = Problem(problem.robot, problem.params, problem.joint_names, problem.values, problem.residuals,
                      directions=problem.directions)
    ev, ref = problem.evaluate(), reference_evaluate(problem)
    rows = problem.blocks[-1].rows if problem.blocks[-1].name == "unordered" else problem.blocks[-2].rows
    assert _relative(ev.r[rows], ref.r[rows]) < RTOL
    assert _relative(ev.J[rows], ref.J[rows]) < RTOL
