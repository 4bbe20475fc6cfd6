"""Accuracy prediction: the world-frame pose Jacobian against finite differences, the covariance against the
calibration's own, and the predicted tool error against synthetic-truth calibrations."""
import numpy as np
import pinocchio as pin
import pytest

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.design.selection import DesignMatrix, select_poses
from robocal.design.candidates import random_candidates
from robocal.model.kinematics import ModelState
from robocal.design.prediction import (accuracy_curve, pose_jacobians, position_weight, predict_parameters,
                                predict_pose_accuracy)
from robocal.design.simulate import perturb, simulate_measurements
from synthetic_cases import ur5_pose_problem

SIGMA = (5e-5, 5e-5)   # tracker: 50 um, 50 urad


def candidates(seed, n, sigma=SIGMA):
    problem = ur5_pose_problem(np.random.default_rng(seed), n, sigma)
    problem.values = random_candidates(problem.robot, problem.joint_names, n, np.random.default_rng(seed))
    return problem


def test_world_pose_jacobian_matches_finite_differences():
    problem = candidates(1, 3)
    problem.robot.base_placement = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 1.1), np.array([1.0, -0.5, 0.2]))
    configs = problem.values
    G = pose_jacobians(problem, "tool0", configs)
    names, eps = problem.params.free_names, 1e-6
    for j, name in enumerate(names):
        poses = []
        for sign in (+1, -1):
            p = problem.params.copy()
            p[name].value += sign * eps
            ms = ModelState(problem.robot, p, problem.joint_names)
            poses.append([ms.sample(v).pose("tool0") for v in configs])
        for v, (a, b) in enumerate(zip(*poses)):
            dp = (a.translation - b.translation) / (2 * eps)
            dphi = pin.log3(a.rotation @ b.rotation.T) / (2 * eps)
            np.testing.assert_allclose(np.concatenate([dp, dphi]), G[v, :, j], atol=1e-7, err_msg=name)


def test_predicted_covariance_equals_the_calibration_covariance():
    problem = candidates(2, 120)
    design = DesignMatrix.from_problem(problem)
    sel = select_poses(design, 25, "D")
    pred = predict_parameters(design, sel.chosen)
    fit = ur5_pose_problem(np.random.default_rng(0), 25, SIGMA)
    fit.values = problem.values[sel.labels]
    truth = perturb(fit.params, np.random.default_rng(3))
    simulate_measurements(fit, truth, np.random.default_rng(4))
    result = calibrate(fit, CalibrationOptions(scale_covariance=False))
    assert result.estimated == pred.names
    # Same linear algebra; only the linearisation point differs (nominal vs the estimate, 2 mm / 0.2 deg
    # apart on ~0.5 m links, a relative change of J of ~4e-3): agree to 1e-2.
    np.testing.assert_allclose(pred.stderr, np.sqrt(np.diag(result.covariance)), rtol=1e-2)


def test_world_axes_follow_the_measurement_frame():
    a, b = candidates(5, 60), candidates(5, 60)
    b.robot.base_placement = pin.SE3(pin.rpy.rpyToMatrix(0, 0, np.pi / 2), np.zeros(3))
    out = []
    for problem in (a, b):
        design = DesignMatrix.from_problem(problem)
        pred = predict_parameters(design, np.arange(60))
        out.append(predict_pose_accuracy(pred, pose_jacobians(problem, "tool0", problem.values[:10])))
    # A tracker turned by 90 deg about z sees the robot's x error as its y error and vice versa.
    np.testing.assert_allclose(out[1].position_axes[:, [1, 0, 2]], out[0].position_axes, rtol=1e-6)
    np.testing.assert_allclose(out[1].position, out[0].position, rtol=1e-6)


def test_predicted_tool_error_matches_synthetic_truth_calibrations():
    """Calibrate K times on the D-optimal poses (fresh truth and noise each time) and compare the achieved RMS
    tool-position error over validation configurations with the prediction.

    Tolerance: the achieved mean square over V configurations in trial t is Q_t / V with
    Q_t = d^T (V W) d, d ~ N(0, C) (linearised), so E[Q_t / V] = tr(CW) and Var = 2 tr((CW)^2). Over K trials
    the mean square has relative standard deviation sqrt(2 / (nu K)) with nu = tr(CW)^2 / tr((CW)^2), and
    the RMS (its square root) half that: s = 1 / sqrt(2 nu K). Here nu ~ 15, K = 40: s ~ 0.03, so the
    required 20 % agreement is a band of more than 5 s (asserted below, so that it stays meaningful),
    leaving room for the linearisation (parameter errors of 2 mm / 0.2 deg move J by ~1e-3 relative).
    """
    problem = candidates(7, 300)
    design = DesignMatrix.from_problem(problem)
    sel = select_poses(design, 30, "D")
    validation = random_candidates(problem.robot, problem.joint_names, 100, np.random.default_rng(8))
    G = pose_jacobians(problem, "tool0", validation)
    pred = predict_parameters(design, sel.chosen)
    predicted = predict_pose_accuracy(pred, G).rms_position
    W = position_weight(G)[np.ix_(pred.columns, pred.columns)]
    CW = pred.covariance @ W
    nu = np.trace(CW) ** 2 / np.trace(CW @ CW)
    trials = 40
    s = 1 / np.sqrt(2 * nu * trials)
    assert 0.2 > 5 * s

    rng = np.random.default_rng(9)
    mean_squares = []
    for _ in range(trials):
        fit = ur5_pose_problem(rng, 30, SIGMA)
        fit.values = problem.values[sel.labels].copy()
        truth = perturb(fit.params, rng)                # every parameter, 2 mm / 0.2 deg
        simulate_measurements(fit, truth, rng)
        calibrate(fit)
        est = ModelState(fit.robot, fit.params, fit.joint_names)
        true = ModelState(fit.robot, truth, fit.joint_names)
        e = np.array([est.sample(v).pose("tool0").translation - true.sample(v).pose("tool0").translation
                      for v in validation])
        mean_squares.append(np.mean(np.sum(e ** 2, axis=1)))
    achieved = np.sqrt(np.mean(mean_squares))
    assert achieved == pytest.approx(predicted, rel=0.2)


def test_accuracy_improves_with_more_poses():
    problem = candidates(10, 150)
    design = DesignMatrix.from_problem(problem)
    G = pose_jacobians(problem, "tool0", problem.values[:50])
    curve = accuracy_curve(design, [10, 20, 40], G)
    rms = [c.prediction.rms_position for c in curve]
    # More well-chosen poses, more information: the predicted error must fall.
    assert rms[0] > rms[1] > rms[2]
    # Roughly 1/sqrt(N) once well determined: 20 -> 40 poses should gain at least 20 %.
    assert rms[2] < 0.8 * rms[1]


def test_pose_jacobians_take_approach_directions_for_backlash():
    from robocal.model.parameters import robot_parameters
    problem = candidates(5, 4)
    joints = problem.joint_names
    problem.params = robot_parameters(problem.robot, joints, "offsets", backlash=True)
    d = np.random.default_rng(5).choice([-1.0, 1.0], size=problem.values.shape)
    G0 = pose_jacobians(problem, "tool0", problem.values)
    Gd = pose_jacobians(problem, "tool0", problem.values, directions=d)
    names = problem.params.free_names
    for k, j in enumerate(joints):
        b, o = names.index(f"{j}.backlash"), names.index(f"{j}.offset")
        assert np.abs(G0[:, :, b]).max() == 0.0                  # at the centre of the play it moves nothing
        assert np.abs(Gd[:, :, o]).max() > 1e-3                  # a real column (not a vacuous comparison)
        np.testing.assert_allclose(Gd[:, :, b], d[:, k, None] * Gd[:, :, o], atol=1e-12)
    with pytest.raises(ValueError, match="shape"):
        pose_jacobians(problem, "tool0", problem.values, directions=d[:, :3])
