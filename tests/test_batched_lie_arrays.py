"""Stacked SO(3)/SE(3) helpers against Pinocchio's own functions, one matrix at a time.

The stacked log3/Jlog3 follow Pinocchio's formulas branch for branch, so they agree to a few ulps; the
angles probe each branch and its threshold: the Taylor expansions below eps^(1/3) (log3) and eps^(1/4)
(Jlog3), the acos branch, and Pinocchio's singular branch within eps^(1/3) of a half turn.
"""
import numpy as np
import pinocchio as pin

from robocal.model import lie_arrays
from robocal.residuals.base import point_jacobian
from robocal.model.lie_arrays import quaternion_matrices

ANGLES = [0.0, 1e-12, 1e-8, 5e-6, 6.0e-6, 1.2e-4, 1.3e-4, 1e-3, 0.5, 2.0, 3.0, np.pi - 1e-3, np.pi - 1e-7, np.pi]


def _rotations():
    rng = np.random.default_rng(1)
    axes = rng.normal(size=(len(ANGLES), 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return np.array([pin.exp3(a * u) for a, u in zip(ANGLES, axes)])


def test_log3_and_jlog3_match_pinocchio_on_every_branch():
    R = _rotations()
    w, theta = lie_arrays.log3(R)
    J = lie_arrays.jlog3(w, theta)
    for k, Rk in enumerate(R):
        # 4 ulps of the angle (pi at most) and of Jlog3's entries (~1 to ~pi^2/4)
        assert np.abs(w[k] - pin.log3(Rk)).max() <= 4 * np.finfo(float).eps * np.pi, ANGLES[k]
        assert np.abs(J[k] - pin.Jlog3(Rk)).max() <= 4 * np.finfo(float).eps * 4.0, ANGLES[k]


def test_adjoints_point_jacobian_and_quaternions_match_pinocchio():
    rng = np.random.default_rng(2)
    poses = [pin.SE3.Random() for _ in range(5)]
    R = np.array([M.rotation for M in poses])
    p = np.array([M.translation for M in poses])
    A = lie_arrays.adjoint_inverse(R, p)
    Ad = lie_arrays.adjoint(R, p)
    x = rng.normal(size=3)
    P = lie_arrays.point_jacobian(R, x)
    for k, M in enumerate(poses):
        assert np.abs(A[k] - M.inverse().toActionMatrix()).max() < 1e-14
        assert np.abs(Ad[k] - M.toActionMatrix()).max() < 1e-14
        assert np.abs(P[k] - point_jacobian(M, x)).max() < 1e-14
    q = np.array([pin.Quaternion(M.rotation).coeffs() for M in poses])
    assert np.abs(quaternion_matrices(q) - R).max() < 1e-14


def test_quaternions_equal_pinocchio_signs_included():
    """Every branch of Eigen's rule (positive trace; each axis leading), half turns and the identity."""
    rng = np.random.default_rng(4)
    Rs = [pin.exp3(rng.normal(0, 2, 3)) for _ in range(500)]
    Rs += [pin.exp3(np.pi * a) for a in np.eye(3)] + [np.eye(3)]
    Rs += [pin.exp3(0.999 * np.pi * v / np.linalg.norm(v)) for v in rng.normal(size=(30, 3))]
    R = np.array(Rs)
    ref = np.array([pin.Quaternion(r).coeffs() for r in R])
    assert np.abs(lie_arrays.quaternions(R) - ref).max() < 1e-15
