"""The parallel CMM under realistic conditions (robocal.systems.pcmm.realism, docs/pcmm_calibration.md): each
simulated error is what it says, and the calibration meets it as stated."""
import warnings
from dataclasses import replace

import numpy as np

from robocal.residuals.sphere_fit import fit_sphere
from robocal.systems.pcmm import (BowedColumns, PreTravel, bowed_readings, calibrate_pcmm, certificate,
                                  inverse_kinematics, random_workspace_poses, reference_artefact, reference_geometry,
                                  reference_placements, simulate_probing, validate)
from robocal.systems.pcmm.compensation import compensate_measurement
from robocal.systems.pcmm.kinematics import axis_directions, rz

GEO, ARTEFACT = reference_geometry(), reference_artefact()
CENTROIDS, YAWS = reference_placements()


def test_certificate_errors_have_the_stated_size_and_keep_the_matrix_symmetric():
    errs, rad = [], []
    for k in range(100):
        cert = certificate(ARTEFACT, np.random.default_rng(k), 1e-6, 0.25e-6)
        assert np.array_equal(cert.distances, cert.distances.T) and np.all(np.diag(cert.distances) == 0)
        errs.append((cert.distances - ARTEFACT.distances)[np.triu_indices(4, 1)])
        rad.append(cert.radii - ARTEFACT.radii)
    # 600 distance and 400 radius draws: an sd's spread is 1/sqrt(2n) (2.9 %, 3.5 %); allow 12 %
    assert abs(np.std(errs) / 1e-6 - 1) < 0.12 and abs(np.std(rad) / 0.25e-6 - 1) < 0.12


def test_bowed_columns_close_every_loop_and_reduce_to_the_straight_machine_without_a_bow():
    Y = random_workspace_poses(50, np.random.default_rng(1))
    assert np.abs(BowedColumns(GEO, np.zeros(4)).readings(Y) - inverse_kinematics(GEO, Y)).max() < 1e-15
    bowed = BowedColumns(GEO, np.array([2e-6, -3e-6, 1e-6, 4e-6]))
    p = bowed.readings(Y)
    # the loop written out independently: D_i = A_i + p e_i + w_i(p) n_i at link length l_i from B_i
    e, n = axis_directions(GEO.tilts)[0], bowed.radial()
    w = bowed.amplitude * (1 - ((p - bowed.centre) / bowed.half_range) ** 2)
    D = GEO.columns[None] + p[:, :, None] * e[None] + w[:, :, None] * n[None]
    B = Y[:, None, :3] + np.einsum("nab,ib->nia", rz(Y[:, 3]), GEO.platform_joints)
    assert np.abs(np.linalg.norm(B - D, axis=2) - GEO.lengths).max() < 1e-12
    assert np.all(np.abs(n @ e.T).diagonal() < 1e-15)             # the bow is across the column's axis
    # a bow of a few um moves the readings by about as much
    assert 1e-7 < np.abs(p - inverse_kinematics(GEO, Y)).max() < 1e-5


def test_pre_travel_puts_the_tip_centres_inside_the_sphere_by_its_amount():
    hits = simulate_probing(GEO, ARTEFACT, CENTROIDS[:1], YAWS[:1], np.random.default_rng(2),
                            pretravel=PreTravel(mean=5e-6))
    tips = compensate_measurement(GEO, hits.readings, hits.theta_cmd)
    radii = [fit_sphere(tips[idx]).radius for idx in hits.groups()[0]]
    # noise-free, straight machine: only the 5 um trigger delay separates the fitted radius from R + r_tip
    assert np.allclose(radii, ARTEFACT.radii + GEO.tip_radius - 5e-6, atol=1e-12)
    lobed = PreTravel(mean=0.0, lobe=0.5e-6)
    assert np.allclose(lobed(np.array([[1.0, 0, 0], [0, 0, 1.0], [np.cos(np.pi / 3), np.sin(np.pi / 3), 0]])),
                       [0.5e-6, 0.0, -0.5e-6])


def calibrated_tip_rms(machine, artefact_used, pretravel=None, start=GEO, true_ik=None):
    hits = simulate_probing(machine, ARTEFACT, CENTROIDS, YAWS, np.random.default_rng(4), pretravel=pretravel)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = calibrate_pcmm(start, hits, artefact_used)
    poses = random_workspace_poses(100, np.random.default_rng(5))
    return validate(machine, replace(fit.geometry, tip_radius=GEO.tip_radius), poses, true_ik=true_ik).tip_rms


def test_a_qualified_constant_pre_travel_is_absorbed_and_errors_outside_the_model_leave_a_floor():
    pre = PreTravel(mean=5e-6)
    qualified = replace(GEO, tip_radius=pre.qualified_tip_radius(GEO.tip_radius))
    true = GEO.perturbed(np.random.default_rng(3).normal(0, 2e-4, 32))
    # noise-free: the qualified probe leaves nothing (rounding of the loop closures, ~1e-15 m); unqualified,
    # the 5 um trigger delay is read as a machine error of that size
    assert calibrated_tip_rms(true, ARTEFACT, pre, qualified) < 1e-10
    assert calibrated_tip_rms(true, ARTEFACT, pre, GEO) > 1e-6
    # the bow the 32 straight-axis parameters cannot hold leaves a floor far above rounding, below its 2 um
    bowed = BowedColumns(true, np.array([2e-6, -2e-6, 2e-6, -2e-6]))
    assert 1e-8 < calibrated_tip_rms(bowed, ARTEFACT, true_ik=bowed_readings) < 2e-6
    # a certificate 1 um off per distance sets the machine's scale and shape wrong: about 1-2 um over the
    # workspace, more than the certificate's own error (the workspace is larger than the artefact)
    assert 1e-7 < calibrated_tip_rms(true, certificate(ARTEFACT, np.random.default_rng(6), 1e-6, 0.0)) < 5e-6
