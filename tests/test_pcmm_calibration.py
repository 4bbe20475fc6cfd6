"""Self-calibration of the 4-PUU parallel CMM from a sphere artefact, through the generic layer
(docs/pcmm_calibration.md, acceptance tests 6-14 of its source document).

Truth: the reference design with all 52 raw error sources drawn from the spec's sigmas; hits
simulated with the RAW model (so the reduction is tested too), 8 placements x 4 spheres x 9 hits.
"""
import warnings
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

import robocal.systems.pcmm.calibration as pc
from robocal.estimation.identifiability import select_base_parameters
from robocal.systems.pcmm import error_model as pe
from robocal.systems.pcmm.compensation import (compensate_command, compensate_measurement, gauge_align,
                                               tip_target_poses, validate)
from robocal.systems.pcmm.machine import (Artefact, reference_artefact, reference_geometry, reference_placements,
                                          reference_raw, simulate_probing)
from robocal.systems.pcmm.kinematics import inverse_kinematics, random_workspace_poses, reduced_names, tip_points
from robocal.systems.pcmm.calibration import (AcquisitionWarning, calibrate_pcmm, effective_rank, machine_jacobian,
                                              predicted_covariance, row_space_projector)
from robocal.residuals.base import Term
from robocal.systems.pcmm.residual import PCMMArtefactResidual

NOM, ART = reference_geometry(), reference_artefact()
CENTROIDS, YAWS = reference_placements()
SIGMA = 1e-6          # axis-reading noise of the spec's noisy run (1 um)


def truth(seed=3, scale=1.0):
    raw = pe.random_raw_errors(reference_raw(), np.random.default_rng(seed), scale)
    return raw, pe.reduce(raw, NOM)


def hits_of(raw, noise=0.0, seed=4, **kw):
    return simulate_probing(raw, ART, CENTROIDS, YAWS, np.random.default_rng(seed), noise=noise, **kw)


def jacobian(hits, use="both", artefact=ART, geo=NOM):
    """(M, 32) Jacobian of the distance/radius rows (scaled by 1/sigma) at machine `geo`."""
    return machine_jacobian(geo, hits, artefact, use)[0]


def ranks(J):
    """(exact rank, effective rank) from the generic base-parameter selection."""
    sel = select_base_parameters(J, reduced_names())
    return sel.rank, effective_rank(sel)


@pytest.fixture(scope="module")
def noisy_run():
    raw, true = truth()
    hits = hits_of(raw, SIGMA)
    return raw, true, hits, calibrate_pcmm(NOM, hits, ART)


def test_rank_27_with_the_five_gauge_vectors_in_the_null_space():
    raw, _ = truth()
    J = jacobian(hits_of(raw))
    assert J.shape == (80, 32) and ranks(J) == (27, 27)
    G = pe.gauge_vectors(NOM)
    # unit gauge vectors: |J g| is at round-off (1e-15 |J|) while the weakest kept direction is ~1e-2 |J|
    assert np.linalg.norm(J @ G.T, axis=0).max() < 1e-10 * np.linalg.norm(J, 2)
    assert np.linalg.matrix_rank(G, tol=1e-6) == 5
    # the five span the numerical null space
    null_space = np.linalg.svd(J)[2][27:].T
    assert np.linalg.svd(null_space.T @ G.T, compute_uv=False).min() > 1 - 1e-8


def test_plugin_jacobians_match_central_differences():
    """The closed-form plug-in's derivatives with respect to the 32 parameters and to the axis readings."""
    raw, true = truth()
    hits = simulate_probing(raw, ART, CENTROIDS[:2], YAWS[:2], np.random.default_rng(5), n_hits=5)
    problem = pc.pcmm_problem(NOM, hits, ART, sigma=1.0)
    res = pc.artefact_residual(problem)
    aux0 = problem.aux_values(res)
    cols = slice(res.n_certificate, len(aux0))

    def rows(aux, readings=None):
        r = PCMMArtefactResidual("fd", NOM, hits if readings is None else replace(hits, readings=readings), ART,
                                 1.0, 1.0)
        return np.concatenate([r.evaluate(k, None, aux).r for k in range(r.n_terms)])

    J = np.vstack([res.evaluate(k, None, aux0).aux[:, cols] for k in range(res.n_terms)])
    # h = 1e-7 m or rad: truncation ~h^2 ~ 1e-14, rounding ~1e-16 / h ~ 1e-9, against |J| ~ 1
    h = 1e-7
    fd = np.column_stack([(rows(aux0 + h * e) - rows(aux0 - h * e)) / (2 * h)
                          for e in np.eye(len(aux0))[cols]])
    assert np.abs(J - fd).max() < 1e-6 * np.abs(J).max()
    G = res.reading_jacobian(aux0)
    rng = np.random.default_rng(6)
    for c in rng.choice(G.shape[1], 6, replace=False):
        d = np.zeros_like(hits.readings)
        d.flat[c] = h
        fd_c = (rows(aux0, hits.readings + d) - rows(aux0, hits.readings - d)) / (2 * h)
        assert np.abs(G[:, c] - fd_c).max() < 1e-6 * np.abs(G).max()


def test_fixed_rotation_drops_the_rank_and_warns():
    raw, _ = truth()
    hits = hits_of(raw, theta_range=0.0)
    with pytest.warns(AcquisitionWarning, match="rotation was not varied"):
        msgs = pc.check_acquisition(NOM, hits, ART)
    # spec reference check: rank 17 (the remaining ten directions are second-order weak, not exactly zero)
    assert ranks(jacobian(hits))[1] == 17 and msgs


def test_one_placement_is_too_few_equations():
    raw, _ = truth()
    hits = simulate_probing(raw, ART, CENTROIDS[:1], YAWS[:1], np.random.default_rng(4))
    with pytest.warns(AcquisitionWarning, match="too few equations"):
        pc.check_acquisition(NOM, hits, ART)
    assert ranks(jacobian(hits))[0] <= 10


def test_noise_free_end_to_end():
    raw, true = truth()
    res = calibrate_pcmm(NOM, hits_of(raw), ART)
    assert res.converged and len(res.history) <= 10 and res.rank == 27
    assert res.rms_before["all"] > 1e-4 and res.rms_after["all"] < 1e-9          # spec: < 1e-6 mm
    v = validate(true, res.geometry, random_workspace_poses(300, np.random.default_rng(8)))
    assert v.tip_rms < 1e-8 and v.pair_rms < 1e-8                                # spec: < 1e-5 mm
    assert all(r.cost >= 0 and r.damping > 0 and r.step_norm >= 0 for r in res.history)
    assert [r.iteration for r in res.history] == list(range(1, len(res.history) + 1))


def test_noisy_end_to_end_improves_by_fifty(noisy_run):
    """1 um axis noise. The residual floor: a fitted radius/centre carries ~sigma * |dE/drho| ~ 1 um
    of noise (27 of 80 rows absorbed by the fit), so the spec's bound of 2 um on the RMS holds."""
    raw, true, hits, res = noisy_run
    assert res.converged
    assert res.rms_before["all"] > 1e-4 and res.rms_after["all"] <= 2e-6
    poses = random_workspace_poses(300, np.random.default_rng(9))
    before, after = validate(true, NOM, poses), validate(true, res.geometry, poses)
    assert before.tip_rms / after.tip_rms >= 50
    assert before.pair_rms / after.pair_rms >= 50


def test_gauge_aware_parameter_check_against_predicted_sigma(noisy_run):
    """Project eps_id - eps_true on the row space of J_E; compare with the first-order covariance of the
    estimator, J^+ (G sigma^2 G^T) J^+T with G = dE/d(readings). Mahalanobis ~ chi2(27): the bound is its
    99.9 % quantile; per component |z| < 4 sigma (Bonferroni over 32 components: 0.2 % false alarms)."""
    raw, true, hits, res = noisy_run
    d = res.geometry.reduced_vector() - true.reduced_vector()
    P = row_space_projector(jacobian(hits, geo=res.geometry))
    z = P @ d
    C = predicted_covariance(res.geometry, hits, ART, SIGMA)
    m = z @ np.linalg.pinv(C, rcond=1e-10, hermitian=True) @ z
    assert m < chi2.ppf(0.999, 27)
    assert np.all(np.abs(z) < 4 * np.sqrt(np.diag(C)) + 1e-15)
    assert np.linalg.norm(z) > 0   # the noise did move the estimate


def test_constraints_alone_identify_but_combined_is_best_conditioned():
    raw, _ = truth()
    hits = hits_of(raw)
    kept = {}
    for use in ("both", "distance", "radius"):
        J = jacobian(hits, use)
        assert ranks(J)[0] == 27, use
        kept[use] = np.linalg.svd(J, compute_uv=False)[26]     # the smallest kept singular value
    assert kept["both"] >= kept["distance"] and kept["both"] >= kept["radius"]


def _ball_bar_hits(raw, n, seed):
    rng = np.random.default_rng(seed)
    bar = Artefact.from_centres([[0.0, 0.0, 0.0], [0.25, 0.0, 0.06]], 0.0127)
    cen = np.column_stack([rng.uniform(-0.06, 0.06, n), rng.uniform(-0.06, 0.06, n), rng.uniform(-0.7, -0.6, n)])
    return bar, simulate_probing(raw, bar, cen, rng.uniform(-np.pi, np.pi, n), rng)


def test_ball_bar_identifies_with_enough_placements_and_warns_with_too_few():
    raw, _ = truth()
    bar, hits = _ball_bar_hits(raw, 24, 31)
    assert ranks(jacobian(hits, artefact=bar)) == (27, 27)
    bar, few = _ball_bar_hits(raw, 5, 32)
    with pytest.warns(AcquisitionWarning, match="too few equations"):
        pc.check_acquisition(NOM, few, bar)


def test_commands_through_identified_ik_reach_the_targets(noisy_run):
    """Spec 12(b): targets in the identified frame, true machine executes; after the rigid gauge
    alignment the RMS is of the order of the validation error (<= 5 um at 1 um noise)."""
    raw, true, hits, res = noisy_run
    rng = np.random.default_rng(10)
    poses = random_workspace_poses(100, rng)
    targets = tip_points(NOM, poses)
    cmd = compensate_command(res.geometry, tip_target_poses(res.geometry, targets, poses[:, 3]))
    reached = compensate_measurement(true, cmd, poses[:, 3])
    assert gauge_align(targets, reached)[2] <= 5e-6
    assert gauge_align(targets, compensate_measurement(
        true, inverse_kinematics(NOM, tip_target_poses(NOM, targets, poses[:, 3])), poses[:, 3]))[2] > 5e-5


def test_gauge_by_constraints_agrees_with_gauge_by_priors():
    raw, true = truth()
    hits = hits_of(raw)
    fix = calibrate_pcmm(NOM, hits, ART)
    assert fix.converged and np.sum(fix.d_eps == 0.0) == 5       # five parameters held: the gauge
    assert fix.gauge == fix.result.unidentifiable and len(fix.gauge) == 5 and fix.rank == 27
    prior = calibrate_pcmm(NOM, hits, ART, gauge="prior")
    assert prior.converged and prior.rank == 27 and np.sum(prior.d_eps == 0.0) == 0
    assert prior.result.prior_only == fix.gauge                  # the same five, now set by their prior
    poses = random_workspace_poses(100, np.random.default_rng(12))
    assert validate(true, fix.geometry, poses).tip_rms < 1e-8
    # the two are one machine up to the gauge: read back the same tips after the rigid alignment
    rho = inverse_kinematics(true, poses)
    assert gauge_align(compensate_measurement(fix.geometry, rho, poses[:, 3]),
                       compensate_measurement(prior.geometry, rho, poses[:, 3]))[2] < 1e-8
    with pytest.raises(ValueError, match="gauge must be one of fix, prior"):
        calibrate_pcmm(NOM, hits, ART, gauge="svd")


def test_loop_stops_when_no_step_lowers_the_cost(monkeypatch):
    raw, _ = truth()
    hits = hits_of(raw)
    real = PCMMArtefactResidual.evaluate
    trials = set()

    def worse_away_from_start(self, k, states, aux):  # every point but the nominal start looks worse
        term = real(self, k, states, aux)
        if np.any(np.asarray(aux)[self.n_certificate:] != 0.0):
            trials.add(np.asarray(aux).tobytes())
            return Term(term.r * 1e6, term.frames, term.aux)
        return term
    monkeypatch.setattr(PCMMArtefactResidual, "evaluate", worse_away_from_start)
    res = calibrate_pcmm(NOM, hits, ART)
    # the generic LM raises its damping x4 per rejected trial up to 1e16 (< 30 trials from 1e-3), then stops:
    # at most 40 distinct trial points (and no loop without end)
    assert res.history == [] and len(trials) <= 40
    assert np.all(res.d_eps == 0.0)                  # no step was taken
    # (the generic LM reads "the damped model predicts no gain" as a fit exact to rounding: see its message)
    assert res.message in ("cost at the rounding level", "no step reduces the cost (local minimum or bad Jacobian)")


def test_three_times_larger_errors_still_converge():
    raw, true = truth(seed=13, scale=3.0)
    res = calibrate_pcmm(NOM, hits_of(raw), ART)
    assert res.converged and res.rms_after["all"] < 1e-9


def test_a_mis_triggered_hit_flags_its_sphere():
    raw, true = truth()
    hits = hits_of(raw, SIGMA)
    k = np.flatnonzero((hits.placement == 2) & (hits.sphere == 1))[4]
    hits.readings[k] += 1e-4          # 0.1 mm on every axis of one trigger
    plain = calibrate_pcmm(NOM, hits, ART)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AcquisitionWarning)
        robust = calibrate_pcmm(NOM, hits, ART, screen=True)
    assert [(g, j) for g, j, _ in robust.flagged] == [(2, 1)]
    assert robust.converged and robust.rms_after["all"] <= 2e-6 < plain.rms_after["all"]
