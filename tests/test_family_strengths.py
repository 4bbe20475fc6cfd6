"""One default-prior strength per scale family (docs/validation.md, "One strength per scale family"): the evidence
recovers each family's prior width on linear synthetic truth, reduces to the common strength with one family,
and its SVD shortcut is the evidence computed directly."""
import numpy as np
import pytest

from robocal.estimation.regularisation import STRENGTHS, choose_strength


def linear_case(rng, lam_length, lam_angle, m=3000, n=60, noise=1.5):
    J = rng.normal(size=(m, 2 * n + 4)) * 0.5
    scales = np.r_[np.full(n, 2.0), np.full(n, 0.5), np.full(4, np.inf)]
    families = ["length"] * n + ["angle"] * n + ["frame"] * 4
    d = np.r_[rng.normal(0, lam_length * 2.0, n), rng.normal(0, lam_angle * 0.5, n), rng.normal(0, 100.0, 4)]
    return J, J @ d + rng.normal(0, noise, m), scales, families


def test_each_family_gets_the_width_its_parameters_were_drawn_from():
    J, r, scales, families = linear_case(np.random.default_rng(3), 0.1, 1.0)
    ev = choose_strength(J, r, scales, families=families)
    # 60 draws a family fix its lam to about 1/sqrt(2 * 60) ~ 9 % (one sigma); the grid steps by 26 %: within 40 %
    assert ev.by_family["length"] == pytest.approx(0.1, rel=0.4)
    assert ev.by_family["angle"] == pytest.approx(1.0, rel=0.4)
    assert set(ev.by_family) == {"length", "angle"}          # the flat columns are no family
    assert ev.noise2 == pytest.approx(1.5 ** 2, rel=0.1)     # 3000 rows: ~2.6 %
    # the common strength lies between the two: the single width the shared strength had to compromise on
    assert 0.1 < ev.strength < 1.0


def test_one_family_is_exactly_the_common_strength():
    J, r, scales, _ = linear_case(np.random.default_rng(4), 0.3, 0.3)
    common = choose_strength(J, r, scales)
    one = choose_strength(J, r, scales, families=["angle"] * (len(scales) - 4) + ["frame"] * 4)
    assert one.by_family == {"angle": common.strength} and common.by_family == {"common": common.strength}
    assert one.noise2 == common.noise2 and np.array_equal(one.stderr, common.stderr)


def dense_log_evidence(A, y, lam, s2):
    """log N(y; 0, s2 I + A diag(lam)^2 A^T) without its 2 pi term, from the dense covariance."""
    B = A * lam
    C = s2 * np.eye(len(y)) + B @ B.T
    _, logdet = np.linalg.slogdet(C)
    return -0.5 * (y @ np.linalg.solve(C, y) + logdet)


def test_no_single_family_move_on_the_grid_raises_the_directly_computed_evidence():
    """The coordinate search's optimum, checked with the dense covariance (no SVD shortcut) and the noise
    variance profiled out by a scan (1e-3 steps in log s2)."""
    rng = np.random.default_rng(5)
    m, n = 80, 12
    A = rng.normal(size=(m, n)) * rng.uniform(0.1, 10, n)
    families = np.array(["length"] * 5 + ["angle"] * 4 + ["relative"] * 3)
    truth = np.r_[np.full(5, 0.05), np.full(4, 2.0), np.full(3, 0.5)]
    y = A @ rng.normal(0, truth) + rng.normal(0, 0.7, m)
    ev = choose_strength(A, y, np.ones(n), families=families)
    s2_grid = np.exp(np.log(ev.noise2) + np.arange(-0.3, 0.3, 1e-3))

    def profiled(by_family):
        lam = np.array([by_family[f] for f in families])
        return max(dense_log_evidence(A, y, lam, s2) for s2 in s2_grid)

    best = profiled(ev.by_family)
    assert dense_log_evidence(A, y, np.array([ev.by_family[f] for f in families]), ev.noise2) == pytest.approx(
        best, abs=1e-4)                                       # the reported noise is the profiled optimum
    for f in ev.by_family:
        i = int(np.argmin(np.abs(STRENGTHS - ev.by_family[f])))
        for j in (i - 1, i + 1):
            if 0 <= j < len(STRENGTHS):
                assert profiled({**ev.by_family, f: STRENGTHS[j]}) <= best + 1e-6, (f, STRENGTHS[j])
    # and it is at least the common strength's evidence: the search starts there
    assert best >= profiled({f: ev.strength for f in ev.by_family}) - 1e-6


def test_a_robot_built_to_tight_lengths_and_loose_angles_gets_a_strength_for_each(tmp_path):
    """Synthetic truth through `calibrate`: a UR5 whose placements are off by up to 0.1 mm but whose angles are off
    by up to 5 mrad, two wrist joints barely moving (so the default prior applies), a tracker at 50 um. The
    evidence gives each family the width its errors were drawn from, and every robot parameter is recovered within
    4 of its posterior standard errors (the largest of 42 normal deviates stays below 4 but for 0.3 % of draws)."""
    from robocal.estimation.calibrate import calibrate
    from robocal.workflows.evaluate import setup_for_data
    from validation_cases import write_case

    cfg, truth, _ = write_case(tmp_path, np.random.default_rng(8), n=30, errors=(1e-4, 5e-3),
                               spread={"wrist_2_joint": 0.02, "wrist_3_joint": 0.02})
    setup = setup_for_data(cfg)
    result = calibrate(setup.problem, setup.options)
    prior = result.default_prior
    assert result.success and prior.applied
    # truth in physical scales (1 % of the 0.83 m size, 10 mrad): lengths 0.058 mm / 8.3 mm = 0.007, angles
    # 2.9 mrad / 10 mrad = 0.29 (uniform bounds over sqrt 3); ~17 directions the data see fix the angles' width to
    # ~1/sqrt(2 * 17) ~ 17 %, the grid steps by 26 %: within 40 %. The lengths' sits near the grid's floor.
    assert prior.by_family["angle"] == pytest.approx(5e-3 / np.sqrt(3) / 0.01, rel=0.4)
    assert prior.by_family["angle"] > 4 * prior.by_family["length"], prior.by_family
    # every robot parameter, also those its prior sets, within 4 posterior standard errors of the truth
    names = [n for n in result.params.free_names if not n.startswith("base.")]
    se = np.sqrt(np.diag(result.covariance))[[result.params.free_names.index(n) for n in names]]
    z = np.array([result.params[n].value - truth[n].value for n in names]) / se
    assert len(z) == 42 and np.max(np.abs(z)) < 4, np.round(z, 2)


def test_the_evidence_criterion_scores_the_prior_calibrate_applies(tmp_path):
    """model_criteria.nominal_evidence (the study's evidence criterion) gives each family its own strength as
    calibrate's default prior does, on the same tight-lengths, loose-angles UR5: the angles' strength near their
    drawn width, above the lengths', and an evidence no lower than at the common strength."""
    from robocal.estimation import model_criteria as mc
    from robocal.workflows.evaluate import setup_for_data
    from validation_cases import write_case

    cfg, _, _ = write_case(tmp_path, np.random.default_rng(8), n=30, errors=(1e-4, 5e-3),
                           spread={"wrist_2_joint": 0.02, "wrist_3_joint": 0.02})
    ev = mc.nominal_evidence(setup_for_data(cfg).problem)
    common = mc.nominal_evidence(setup_for_data(cfg).problem, strengths=[ev.strength])   # one candidate: no search
    assert set(ev.by_family) == {"length", "angle"}
    assert ev.by_family["angle"] == pytest.approx(5e-3 / np.sqrt(3) / 0.01, rel=0.4)   # as in calibrate, above
    assert ev.by_family["angle"] > 4 * ev.by_family["length"], ev.by_family
    assert ev.log_evidence >= common.log_evidence - 1e-9


@pytest.mark.parametrize("n_rest", [0, 40])
def test_the_profiled_noise_variance_is_the_minimum_of_a_fine_scan(n_rest):
    """profiled_log_evidence's Newton steps (with its analytic slope and curvature in log s2) land on the
    maximum of the evidence over s2 that a scan at 1e-4 steps finds, for candidates spread over many decades."""
    from robocal.estimation.regularisation import profiled_log_evidence
    rng = np.random.default_rng(11)
    d2 = np.exp(rng.normal(0, 4, (12, 25)))
    z2 = rng.exponential(1.0, (12, 25)) * np.exp(rng.normal(0, 2, (12, 1)))
    rest = 35.0 if n_rest else 0.0
    values, s2 = profiled_log_evidence(d2, z2, rest, n_rest, 1.0)
    for c in range(len(d2)):
        t = np.log(s2[c]) + np.arange(-0.5, 0.5, 1e-4)
        v = np.exp(t)[:, None] + d2[c]
        scan = -0.5 * (np.sum(z2[c] / v, axis=1) + np.sum(np.log(v), axis=1) + rest * np.exp(-t) + n_rest * t)
        assert values[c] >= scan.max() - 1e-9
        assert abs(t[np.argmax(scan)] - np.log(s2[c])) < 2e-4


def test_the_noise_variance_s_slope_and_curvature_match_finite_differences():
    """regularisation.noise_slope_and_curvature against central differences of neg_log_evidence in t = log s2,
    with and without rows outside the columns' span, at t across decades (h = 1e-4: truncation ~1e-8 relative)."""
    from robocal.estimation.regularisation import neg_log_evidence, noise_slope_and_curvature
    rng = np.random.default_rng(12)
    d2 = np.exp(rng.normal(0, 3, (5, 9)))
    z2 = rng.exponential(1.0, (5, 9))
    h = 1e-4
    for rest, n_rest in ((0.0, 0), (17.0, 30)):
        for t0 in (-4.0, 0.0, 3.0):
            t = np.full(5, t0)
            g, c = noise_slope_and_curvature(t, d2, z2, rest, n_rest)
            f = [neg_log_evidence((t + k * h)[:, None], d2, z2, rest, n_rest)[:, 0] for k in (-1, 0, 1)]
            np.testing.assert_allclose(g, (f[2] - f[0]) / (2 * h), rtol=1e-6, atol=1e-7)
            np.testing.assert_allclose(c, (f[2] - 2 * f[1] + f[0]) / h ** 2, rtol=1e-4, atol=1e-4)
