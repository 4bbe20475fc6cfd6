"""The sphere-artefact residual (centre distances + radii of probed spheres) on a serial arm with a probe."""
import numpy as np
import pytest

from robocal import load_example
from robocal.errors import InputError
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.testing import assert_problem_jacobian
from robocal.residuals.sphere_artefact import SphereArtefactResidual, artefact_rows


def _arm_problem(use="both", tip_unknown=False):
    rng = np.random.default_rng(21)
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True})
    for p in params:
        p.value = rng.normal(0, 1e-3)
    q0 = np.array([0.3, -1.2, 1.4, -1.6, -1.5, 0.2])
    values = q0 + rng.normal(0, 0.05, (2 * 3 * 5, 6))   # 2 placements x 3 spheres x 5 hits
    placements = [[np.arange(15 * g + 5 * j, 15 * g + 5 * j + 5) for j in range(3)] for g in range(2)]
    D = np.array([[0, 0.2, 0.25], [0.2, 0, 0.15], [0.25, 0.15, 0]])
    res = SphereArtefactResidual("artefact", "tool0", placements, [0.0127] * 3, D, tip_radius=1e-3,
                                 point=(0.0, 0.0, 0.05), use=use, tip_radius_unknown=tip_unknown)
    return Problem(robot, params, joints, values, [res]), res


def test_residual_jacobian_on_a_serial_arm_matches_finite_differences():
    problem, res = _arm_problem(tip_unknown=True)
    assert res.n_terms == 2 and res.dim == 6 and len(res.term_samples(1)) == 15
    # rows are scaled by 1/sigma = 1e6; central differences with h = 1e-6: truncation ~h^2, the fits
    # converge to 1e-15 relative, so the relative error floor is ~1e-8
    assert_problem_jacobian(problem, h=1e-6, tol=1e-6)
    assert "artefact.tip_radius" in problem.params.free_names


def test_use_switches_rows_off_and_combined_stacks_both():
    both = _arm_problem("both")[0].evaluate(jacobian=False).raw
    dist = _arm_problem("distance")[0].evaluate(jacobian=False).raw
    rad = _arm_problem("radius")[0].evaluate(jacobian=False).raw
    assert len(both) == 12 and len(dist) == 6 and len(rad) == 6
    np.testing.assert_allclose(np.sort(both), np.sort(np.concatenate([dist, rad])), rtol=0, atol=1e-15)


def test_rows_vanish_for_points_on_the_reference_spheres():
    rng = np.random.default_rng(22)
    centres = np.array([[0, 0, 0], [0.2, 0, 0.02], [0.2, 0.15, 0]])
    radii = np.array([0.0127, 0.01, 0.015])
    D = np.linalg.norm(centres[:, None] - centres[None], axis=2)
    pts = []
    for c, r in zip(centres, radii):
        n = rng.normal(size=(7, 3))
        n[:, 2] = np.abs(n[:, 2])
        pts.append(c + (r + 1e-3) * n / np.linalg.norm(n, axis=1, keepdims=True))
    rows, dX, fits = artefact_rows(pts, D, radii, 1e-3)
    assert np.abs(rows).max() < 1e-14 and dX.shape == (6, 63)
    rows2, _, _ = artefact_rows(pts, D + 1e-4, radii, 1e-3)
    np.testing.assert_allclose(rows2[:3], -1e-4, atol=1e-14)


def test_bad_input_names_the_field():
    with pytest.raises(InputError, match="at least 4"):
        SphereArtefactResidual("a", "tool0", [[np.arange(3), np.arange(3, 8)]], [0.01, 0.01], np.zeros((2, 2)))
    with pytest.raises(InputError, match="distances"):
        SphereArtefactResidual("a", "tool0", [[np.arange(4), np.arange(4, 8)]], [0.01, 0.01], np.zeros((3, 3)))
    with pytest.raises(InputError, match="use"):
        SphereArtefactResidual("a", "tool0", [[np.arange(4), np.arange(4, 8)]], [0.01, 0.01], np.zeros((2, 2)),
                               use="diameter")
