"""The 4-PUU CMM on its URDF with loop closures: generic placement parameters and the generic
sphere-artefact residual agree with the closed-form residual plug-in the calibration uses (the
independent check of that plug-in's rows and Jacobian)."""
from pathlib import Path

import numpy as np

from robocal import load_urdf
from robocal.model.kinematics import ModelState
from robocal.systems.pcmm import error_model as pe
from robocal.systems.pcmm.machine import (build_urdf, generic_parameters, reference_artefact, reference_geometry,
                                     reference_placements, reference_raw, simulate_probing, urdf_configuration,
                                     write_urdf)
from robocal.systems.pcmm.kinematics import (inverse_kinematics, random_workspace_poses, tip_error_jacobian,
                                                tip_points)
from robocal.systems.pcmm.calibration import artefact_residual, pcmm_problem, reduced_columns
from robocal.estimation.problem import Problem
from robocal.residuals.sphere_artefact import SphereArtefactResidual
from robocal.testing import assert_same_text_and_numbers

URDF = Path(__file__).parents[1] / "urdf" / "pcmm_4puu.urdf"
NOM = reference_geometry()


def test_shipped_urdf_is_the_builders_reference_machine():
    assert_same_text_and_numbers(URDF.read_text(encoding="utf-8"), build_urdf(NOM), what=str(URDF))


def test_urdf_fk_equals_closed_form_fk_on_a_perturbed_machine(tmp_path):
    true = pe.reduce(pe.random_raw_errors(reference_raw(), np.random.default_rng(41)), NOM)
    robot = load_urdf(write_urdf(true, tmp_path / "true.urdf"))
    ps, _ = generic_parameters()
    ms = ModelState(robot, ps, robot.loops.actuated)
    Y = random_workspace_poses(6, np.random.default_rng(42))
    rho = inverse_kinematics(true, Y)
    for k in range(len(Y)):   # assembled from the URDF's neutral configuration, not from the answer
        s = ms.sample(rho[k])
        assert np.abs(s.pose("probe_tip").translation - tip_points(true, Y[k:k + 1])[0]).max() < 1e-10


def test_generic_parameters_move_the_tip_like_their_reduced_parameters():
    """Perturbing a generic parameter == perturbing its reduced one (first order, through the loops)."""
    robot = load_urdf(URDF)
    ps, _ = generic_parameters()
    ms = ModelState(robot, ps, robot.loops.actuated)
    Y = random_workspace_poses(4, np.random.default_rng(43))
    rho = inverse_kinematics(NOM, Y)
    Jc = tip_error_jacobian(NOM, Y, rho)
    for k in range(len(Y)):
        s = ms.sample(rho[k], q_guess=urdf_configuration(robot, NOM, Y[k], rho[k]))
        Jg = s.pose("probe_tip").rotation @ s.frame_parameter_jacobian("probe_tip")[:3]
        assert np.abs(Jg - Jc[k]).max() < 1e-10


def test_sphere_residual_jacobian_through_the_generic_layer_equals_the_closed_form():
    true = pe.reduce(pe.random_raw_errors(reference_raw(), np.random.default_rng(44)), NOM)
    art = reference_artefact()
    cen, yaw = reference_placements()
    hits = simulate_probing(true, art, cen[:2], yaw[:2], np.random.default_rng(45), n_hits=5)
    robot = load_urdf(URDF)
    ps, _ = generic_parameters()
    groups = hits.groups()
    res = SphereArtefactResidual("artefact", "probe_tip", groups, art.radii, art.distances,
                                 tip_radius=NOM.tip_radius, sigma_distance=1.0, sigma_radius=1.0)
    problem = Problem(robot, ps, robot.loops.actuated, hits.readings, [res])
    closed_form = pcmm_problem(NOM, hits, art, sigma=1.0)
    ev_c = closed_form.evaluate()
    J_c = ev_c.J[:, reduced_columns(closed_form)]
    poses = artefact_residual(closed_form).last.poses
    for i, (y, r) in enumerate(zip(poses, hits.readings)):
        problem.warm_starts[i] = urdf_configuration(robot, NOM, y, r)
    ev_g = problem.evaluate()
    np.testing.assert_allclose(ev_g.r, ev_c.r, rtol=0, atol=1e-12)
    # columns: generic_parameters() is in the reduced order, and Problem keeps that order for robot kinds
    assert np.abs(ev_g.J - J_c).max() < 1e-9 * np.abs(J_c).max()
