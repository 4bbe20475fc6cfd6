"""4-PUU parallel CMM closed-form kinematics and error model (acceptance tests 1-4, 12c-d of the
specification behind docs/pcmm_calibration.md)."""
import numpy as np
import pytest

from robocal.errors import AssemblyError, InputError
from robocal.systems.pcmm import error_model as pe
from robocal.systems.pcmm.machine import reference_geometry, reference_raw
from robocal.systems.pcmm.kinematics import (axis_directions, forward_kinematics, ik_jacobian,
                                                inverse_kinematics, pose_error_jacobian, random_workspace_poses,
                                                reduced_names, rz, tip_error_jacobian, tip_points)
from robocal.systems.pcmm.compensation import first_order_pose_correction

GEO = reference_geometry()


def test_ik_fk_round_trip_and_newton_iterations():
    rng = np.random.default_rng(1)
    Y = random_workspace_poses(1000, rng)
    rho = inverse_kinematics(GEO, Y)
    # start within 50 mm / 0.2 rad of the answer
    y0 = Y + np.column_stack([rng.uniform(-0.05, 0.05, (1000, 3)) / np.sqrt(3), rng.uniform(-0.2, 0.2, 1000)])
    Yf, it = forward_kinematics(GEO, rho, y0)
    # 1e-9 mm of the spec = 1e-12 m; Newton converged to a 1e-13 step, so round-off ~1e-15 remains
    assert np.abs(Yf - Y).max() < 1e-12
    assert it <= 10


def test_loop_closure_of_ik_outputs():
    rng = np.random.default_rng(2)
    Y = random_workspace_poses(200, rng)
    rho = inverse_kinematics(GEO, Y)
    e = axis_directions(GEO.tilts)[0]
    B = Y[:, None, :3] + np.einsum("nab,ib->nia", rz(Y[:, 3]), GEO.platform_joints)
    D = GEO.columns[None] + rho[:, :, None] * e[None]
    assert np.abs(np.linalg.norm(B - D, axis=2) - GEO.lengths).max() < 1e-12


def test_unreachable_pose_and_bad_geometry_raise():
    with pytest.raises(AssemblyError, match="out of reach"):
        inverse_kinematics(GEO, [1.0, 0.0, -0.6, 0.0])
    with pytest.raises(InputError, match="lengths"):
        type(GEO)(GEO.columns, GEO.tilts, GEO.platform_joints, np.ones(3))


def _perturbed_truth(rng, scale=1.0):
    raw = pe.random_raw_errors(reference_raw(), rng, scale)
    return raw, pe.reduce(raw, GEO)


def test_ik_jacobian_matches_finite_differences():
    rng = np.random.default_rng(3)
    _, geo = _perturbed_truth(rng)
    Y = random_workspace_poses(20, rng)
    J = ik_jacobian(geo, Y)
    h = 1e-6
    for k in range(4):
        d = np.zeros(4)
        d[k] = h
        fd = (inverse_kinematics(geo, Y + d) - inverse_kinematics(geo, Y - d)) / (2 * h)
        # central differences: truncation ~h^2 |p'''| ~ 1e-12, round-off ~1e-16/h = 1e-10
        assert np.abs(fd - J[:, :, k]).max() < 1e-8


def test_error_jacobian_matches_finite_differences_of_fk():
    """J_p = J_q^-1 J_eps (B_i sign: +1 for dl = l_actual - l_nominal) vs central FD of the exact FK."""
    rng = np.random.default_rng(4)
    _, geo = _perturbed_truth(rng)
    Y = random_workspace_poses(20, rng)
    assert np.ptp(Y[:, 3]) > 0.2        # theta != 0 included
    rho = inverse_kinematics(geo, Y)
    J = pose_error_jacobian(geo, Y, rho)
    x0 = geo.reduced_vector()
    h = 1e-6
    fd = np.zeros_like(J)
    for k in range(len(x0)):
        d = np.zeros(len(x0))
        d[k] = h
        yp = forward_kinematics(geo.with_reduced(x0 + d), rho, Y)[0]
        ym = forward_kinematics(geo.with_reduced(x0 - d), rho, Y)[0]
        fd[:, :, k] = (yp - ym) / (2 * h)
    rel = np.abs(fd - J).max() / np.abs(J).max()
    assert rel < 1e-5
    T = tip_error_jacobian(geo, Y, rho)
    X0 = tip_points(geo, Y)
    assert T.shape == (20, 3, 32) and np.isfinite(X0).all()


def test_reduction_of_the_52_raw_errors_is_exact():
    rng = np.random.default_rng(5)
    raw, geo = _perturbed_truth(rng)
    assert len(pe.raw_names()) == 52 and len(reduced_names()) == 32
    Y = random_workspace_poses(50, rng)
    rho = pe.raw_inverse_kinematics(raw, Y)
    assert np.abs(rho - inverse_kinematics(geo, Y)).max() < 1e-13
    Yf = forward_kinematics(geo, rho, Y + 0.01)[0]
    # FK of the reduced machine on the raw machine's readings reproduces the raw poses (spec: 1e-9 mm)
    assert np.abs(tip_points(geo, Yf) - tip_points(geo, Y)).max() < 1e-12


def test_first_order_compensation_leaves_a_second_order_remainder():
    """Spec 12(c): FK_nom + J_p d_eps with the true reduced d_eps; remainder < 1.5 % of the error."""
    rng = np.random.default_rng(6)
    _, true = _perturbed_truth(rng)
    d_eps = true.reduced_vector() - GEO.reduced_vector()
    Y = random_workspace_poses(200, rng)
    rho = inverse_kinematics(true, Y)
    X_true = tip_points(true, Y)
    Y_nom = forward_kinematics(GEO, rho, Y)[0]
    err_nom = np.linalg.norm(tip_points(GEO, Y_nom) - X_true, axis=1)
    Y_comp = Y_nom + first_order_pose_correction(GEO, d_eps, Y_nom, rho)
    err_comp = np.linalg.norm(tip_points(GEO, Y_comp) - X_true, axis=1)
    ratio = np.sqrt(np.mean(err_comp ** 2) / np.mean(err_nom ** 2))
    assert np.sqrt(np.mean(err_nom ** 2)) > 2e-4       # the errors are there (spec run: 1.3 mm)
    assert ratio < 0.015


def test_gauge_vectors_leave_every_tip_distance_unchanged():
    """The five gauge directions move the whole measured point cloud rigidly (to first order)."""
    rng = np.random.default_rng(7)
    Y = random_workspace_poses(30, rng)
    rho = inverse_kinematics(GEO, Y)
    T = tip_error_jacobian(GEO, Y, rho)
    X = tip_points(GEO, Y)
    for g in pe.gauge_vectors(GEO):
        dX = T @ g
        # a rigid motion's velocity field: dX_i = v + w x X_i; fit (v, w) by least squares and check residual
        A = np.vstack([np.hstack([np.eye(3), -np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]])])
                       for x in X])
        sol, *_ = np.linalg.lstsq(A, dX.reshape(-1), rcond=None)
        assert np.abs(A @ sol - dX.reshape(-1)).max() < 1e-12
