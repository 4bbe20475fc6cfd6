"""Analytic derivatives of the compensated strut lengths against central finite differences.

Central differences with step h have error ~ h^2 f'''/6 + eps |f| / h ~ 1e-10 here; the spec asks
for agreement to 1e-7 (test 5), which leaves a wide margin on the side of false alarms only.
"""
import numpy as np
import pinocchio as pin
import pytest

from robocal.systems.floating_nut.geometry import reference_fixture, tangent_basis
from robocal.systems.floating_nut.kinematics import FloatingNutKinematics

DEG = np.pi / 180
H = 1e-6
FD_TOL = 1e-7


def random_poses(geometry, n, seed):
    rng = np.random.default_rng(seed)
    return geometry.p0 + np.hstack([rng.uniform(-0.1, 0.1, (n, 3)), rng.uniform(-10, 10, (n, 3)) * DEG])


def tilted_geometry(euler="ZYX-fixed"):
    """Non-radial Hooke axes, a tilted home pose, mixed signs and leads: nothing lines up by chance."""
    g = reference_fixture()
    rng = np.random.default_rng(21)
    return g.with_changes(base_axes=g.base_axes + rng.normal(0, 0.4, (6, 3)),
                          plat_axes=g.plat_axes + rng.normal(0, 0.4, (6, 3)),
                          p0=[0.02, -0.01, 0.82, 3 * DEG, -2 * DEG, 4 * DEG],
                          sigma=[1, -1, 1, 1, -1, -1], lead=[0.01, 0.005, 0.02, 0.01, 0.008, 0.012],
                          euler=euler)


def central(f, x, h=H):
    cols = []
    for k in range(x.size):
        dx = np.zeros_like(x)
        dx[k] = h
        cols.append((f(x + dx) - f(x - dx)) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("geometry", [reference_fixture(), tilted_geometry(), tilted_geometry("XYZ-moving")],
                         ids=["fixture", "tilted", "tilted-XYZ"])
def test_pose_jacobians_match_finite_differences(geometry):
    kin = FloatingNutKinematics(geometry)
    for p in random_poses(geometry, 10, seed=22):
        Jl, Jt = kin.length_and_roll_jacobians(p)
        assert np.abs(Jl - central(kin.effective_lengths, p)).max() < FD_TOL
        assert np.abs(Jt - central(kin.nut_rotation, p)).max() < FD_TOL
        Jc = kin.jacobian(p)
        assert np.abs(Jc - central(kin.ik, p)).max() < FD_TOL
        np.testing.assert_allclose(Jc, Jl + (geometry.sigma * geometry.lead / (2 * np.pi))[:, None] * Jt,
                                   atol=1e-15)
        assert np.abs(kin.jacobian(p, compensate=False) - Jl).max() == 0.0


def test_lead_derivative_matches_finite_differences():
    g = tilted_geometry()
    poses = random_poses(g, 20, seed=23)
    analytic = FloatingNutKinematics(g).lead_derivative(poses)
    for leg in range(6):
        def lc(lead_value, leg=leg):
            lead = g.lead.copy()
            lead[leg] = lead_value[0]
            return FloatingNutKinematics(g.with_changes(lead=lead)).ik(poses)
        fd = central(lc, g.lead[[leg]])[..., 0]                  # (20, 6): every leg's l_c
        np.testing.assert_allclose(fd[:, leg], analytic[:, leg], atol=FD_TOL)
        others = np.delete(fd, leg, axis=1)
        assert np.abs(others).max() == 0.0                      # a lead moves its own strut only


def rotated_axis(axis, delta):
    return pin.exp3(np.asarray(delta, dtype=float)) @ axis


def test_axis_derivatives_match_finite_differences():
    g = tilted_geometry()
    poses = random_poses(g, 8, seed=24)
    base, plat = FloatingNutKinematics(g).axis_derivatives(poses)
    for leg in range(6):
        for which, analytic in (("base_axes", base), ("plat_axes", plat)):
            def lc(delta, leg=leg, which=which):
                axes = getattr(g, which).copy()
                axes[leg] = rotated_axis(axes[leg], delta)
                return FloatingNutKinematics(g.with_changes(**{which: axes})).ik(poses)
            fd = central(lc, np.zeros(3))                      # (8, 6, 3)
            np.testing.assert_allclose(fd[:, leg], analytic[:, leg], atol=FD_TOL)
            assert np.abs(np.delete(fd, leg, axis=1)).max() == 0.0
    # the rotation about an axis itself changes nothing
    along = np.einsum("nlk,lk->nl", base, g.base_axes)
    assert np.abs(along).max() < 1e-15
    # the two calibration angles per axis: projection on a deterministic tangent basis
    e = tangent_basis(g.base_axes)
    assert np.allclose(np.einsum("lik,lk->li", e, g.base_axes), 0) and np.allclose(np.linalg.norm(e, axis=2), 1)


def test_axis_derivatives_vanish_at_home():
    g = tilted_geometry()
    base, plat = FloatingNutKinematics(g).axis_derivatives(g.p0)
    assert np.abs(base).max() < 1e-15 and np.abs(plat).max() < 1e-15    # theta(p0) = 0 for any axes


def test_fd_mode_agrees_with_analytic():
    kin = FloatingNutKinematics(reference_fixture())
    p = random_poses(kin.geometry, 5, seed=25)
    assert np.abs(kin.jacobian(p, mode="fd") - kin.jacobian(p)).max() < FD_TOL


@pytest.mark.parametrize("geometry", [reference_fixture(), tilted_geometry(), tilted_geometry("XYZ-moving")],
                         ids=["fixture", "tilted", "tilted-XYZ"])
def test_single_pose_fk_jacobian_matches_the_analytic_one(geometry):
    """The lean single-pose FK builds J_c and J_l from quadratic forms in [R, t, 1] (floating_nut_fk.py):
    they must equal the batch analytic matrices, and its residual the compensated IK."""
    kin = FloatingNutKinematics(geometry)
    solver = kin._single_pose_solver()
    lengths = kin.ik(geometry.p0)
    for p in random_poses(geometry, 10, seed=26):
        Qm, q, l, x, y, dR, e = solver._evaluate(p.tolist(), lengths, True)
        np.testing.assert_allclose(e, lengths - kin.ik(p), atol=1e-14)
        np.testing.assert_allclose(solver._jacobian(Qm, q, l, x, y, dR, True), kin.jacobian(p), atol=1e-13)
        Jl = kin.length_and_roll_jacobians(p)[0]
        np.testing.assert_allclose(solver._jacobian(Qm, q, l, x, y, dR, False), Jl, atol=1e-13)
