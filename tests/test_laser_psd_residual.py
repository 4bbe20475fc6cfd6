"""The laser-line residual's rows: invariant to a spin about the beam and to moving everything rigidly,
|r| = distance of the point from the beam, analytic Jacobian exact away from the solution."""
import numpy as np
import pytest

from laser_psd_cases import MOUNT, exact_readings, joints, readings_for, plans, robot
from robocal.systems.laser_psd.calibration import LaserMount, beams, zero_offset_problem
from robocal.testing import assert_problem_jacobian

COAXIAL = LaserMount([0.0, 0.0, 0.08], [0.0, 0.0, 1.0])
TILTED = LaserMount([0.01, 0.04, 0.08], [0.2, -0.1, 1.0])
PERTURB = [0.01, -0.02, 0.015, 0.01, -0.01, 0.02]


def _perturbed(mount, preset="offsets", frames=None):
    """Every aux free (target, origin, tilt) and all of them and the offsets away from the fit."""
    q = readings_for(mount, plans()["patent"])
    problem = zero_offset_problem(robot(), joints(), q, mount, sigma=1.0, mount_free=True, preset=preset,
                                  frames=frames)
    for j, d in zip(joints(), PERTURB):
        problem.params[f"{j}.offset"].value = d
    for name, dv in [("psd.target.x", 0.003), ("psd.target.z", -0.002), ("psd.origin.x", 0.002),
                     ("psd.origin.y", -0.001), ("psd.origin.z", 0.004), ("psd.tilt_a", 0.02), ("psd.tilt_b", -0.03)]:
        problem.params[name].value += dv
    return problem


@pytest.mark.parametrize("mount", [MOUNT, COAXIAL, TILTED], ids=["off_axis", "coaxial", "tilted"])
def test_jacobian_matches_finite_differences_at_non_zero_residuals(mount):
    problem = _perturbed(mount)
    assert np.abs(problem.evaluate(jacobian=False).raw).max() > 1e-3
    # central differences, h = 1e-6: truncation ~ h^2 |r'''| and rounding ~ eps |r| / h, both < 1e-7
    assert_problem_jacobian(problem, h=1e-6, tol=1e-7)


def test_jacobian_with_link_parameters_free():
    # the basis is carried by link 5, so its pose's derivative (every upstream parameter) enters too
    problem = _perturbed(TILTED, preset="full", frames={"tool0": ("tx", "ty", "tz", "rx", "ry", "rz")})
    assert_problem_jacobian(problem, h=1e-6, tol=1e-7)


def test_rows_are_the_distance_from_the_beam():
    problem = _perturbed(TILTED)
    r = problem.evaluate(jacobian=False).raw.reshape(-1, 2)
    params = problem.params
    a, b = params["psd.tilt_a"].value, params["psd.tilt_b"].value
    R0 = TILTED.placement().rotation
    u = R0 @ np.array([a, b, 1.0]) / np.linalg.norm([a, b, 1.0])
    mount = LaserMount([params[f"psd.origin.{c}"].value for c in "xyz"], u)
    O, U = beams(robot(), params, joints(), problem.values, mount)
    P = np.array([params[f"psd.target.{c}"].value for c in "xyz"])
    dist = np.linalg.norm(np.cross(P - O, U), axis=1)
    assert np.abs(np.linalg.norm(r, axis=1) - dist).max() < 1e-15


def test_spin_about_a_coaxial_beam_leaves_the_rows_unchanged():
    problem = zero_offset_problem(robot(), joints(), readings_for(COAXIAL, plans()["three_fans"]), COAXIAL)
    for j, d in zip(joints(), PERTURB):
        problem.params[f"{j}.offset"].value = d
    ev = problem.evaluate()
    r0 = ev.raw
    assert np.abs(r0).max() > 1e-2                                   # far from the fit
    col = problem.params.free_names.index("joint_6.offset")
    assert np.abs(ev.J[:, col]).max() < 1e-12 * np.abs(ev.J).max()
    for spin in (0.3, -2.0):                                         # joint 6 turns the flange about the beam
        problem.params["joint_6.offset"].value = PERTURB[5] + spin
        assert np.abs(problem.evaluate(jacobian=False).raw - r0).max() < 1e-12


def test_turning_the_base_and_the_point_together_leaves_the_rows_unchanged():
    """Why the basis is carried by the robot (link 5), not fixed in the measurement frame."""
    problem = zero_offset_problem(robot(), joints(), exact_readings("patent"), MOUNT)
    for j, d in zip(joints(), PERTURB):
        problem.params[f"{j}.offset"].value = d
    r0 = problem.evaluate(jacobian=False).raw
    assert np.abs(r0).max() > 1e-3
    b = 0.4
    Rb = np.array([[np.cos(b), -np.sin(b), 0], [np.sin(b), np.cos(b), 0], [0, 0, 1]])
    c = np.array([problem.params[f"psd.target.{k}"].value for k in "xyz"])
    problem.params["joint_1.offset"].value += b
    for k, v in zip("xyz", Rb @ c):
        problem.params[f"psd.target.{k}"].value = v
    assert np.abs(problem.evaluate(jacobian=False).raw - r0).max() < 1e-12
