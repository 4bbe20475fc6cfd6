"""An example CI suite for a team that maintains a robot model (here the UR5 of example-robot-data).

Run:  pytest examples/ci_suite                        (model and derivative checks)
      pytest examples/ci_suite --robocal-dataset cal.yaml --robocal-urdf ur5_calibrated.urdf
                                                      (+ the calibrated model against recorded data)
"""
import pytest

from robocal.testing import (assert_calibration_recovers, assert_frame_jacobians, assert_problem_jacobian,
                             assert_reproduces_dataset, assert_urdf_loads)

FRAMES = ["base_link", "tool0"]
SIGMA = 5e-5   # the tracker's noise, m and rad


@pytest.mark.robocal_robot("ur5")
def test_model_loads_with_its_frames(robocal_robot):
    # the fixture loaded it; this re-checks the file, the frames and (for closed chains) the home assembly
    assert_urdf_loads(robocal_robot.urdf_path, FRAMES)


def test_residual_derivatives_match_finite_differences(robocal_synthetic):
    case = robocal_synthetic("ur5", n_samples=3)
    assert_problem_jacobian(case.problem)


def test_frame_derivatives_match_finite_differences(robocal_synthetic):
    case = robocal_synthetic("ur5", n_samples=1)
    p = case.problem
    assert_frame_jacobians(p.robot, case.truth, p.joint_names, p.values[0], "tool0")


def test_calibration_recovers_a_synthetic_truth(robocal_synthetic):
    case = robocal_synthetic("ur5", n_samples=40)
    assert_calibration_recovers(case.problem, case.truth)


def test_model_reproduces_the_recorded_dataset(robocal_dataset, robocal_urdf):
    # RMS within 1.25 sigma and no row beyond 5 sigma (see docs/ci_checks.md for the derivation)
    assert_reproduces_dataset(robocal_dataset, robocal_urdf,
                              rms={"length": 1.25 * SIGMA, "angle": 1.25 * SIGMA},
                              max={"length": 5 * SIGMA, "angle": 5 * SIGMA})
