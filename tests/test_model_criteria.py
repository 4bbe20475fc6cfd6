"""Model-selection criteria from one fit (robocal.estimation.model_criteria): against brute-force refits and
dense Gaussian densities where they are exact, and on synthetic truth."""
import numpy as np
import pytest
import scipy.linalg
import scipy.stats

from robocal.estimation import cross_validate, kfold
from robocal.estimation import model_criteria as mc
from robocal.estimation.calibrate import calibrate
from robocal.workflows.evaluate import setup_for_data
from validation_cases import SIGMA, write_case


def _linear_case(rng, n_samples=20, n_par=5, prior_cols=(3, 4), prior_sigma=0.5):
    """A linear least-squares problem shaped like a calibration: three rows per sample, two parameters with a
    Gaussian prior (prior rows last). Returns the Linearised at the solution, X, y, P."""
    X = rng.normal(size=(3 * n_samples, n_par))
    y = X @ rng.normal(size=n_par) + rng.normal(0, 0.3, 3 * n_samples)
    P = np.zeros((len(prior_cols), n_par))
    for k, j in enumerate(prior_cols):
        P[k, j] = 1.0 / prior_sigma
    A = np.vstack([X, P])
    theta = np.linalg.lstsq(A, np.concatenate([y, np.zeros(len(P))]), rcond=None)[0]
    r = A @ theta - np.concatenate([y, np.zeros(len(P))])
    m = len(r)
    data = np.arange(m) < len(y)
    sample = np.where(data, np.arange(m) // 3, -1)
    lin = mc.Linearised([f"p{j}" for j in range(n_par)], A, r, data, sample, np.ones(m),
                        np.where(data, "length", "prior"), np.where(data, np.arange(m) // 3, 10 ** 9 + np.arange(m)),
                        np.zeros(m, int), np.where(data, "b", "priors"))
    return lin, X, y, P


def test_approximate_loo_equals_brute_force_refits_of_a_linear_problem():
    rng = np.random.default_rng(3)
    lin, X, y, P = _linear_case(rng)
    folds = [np.array([s]) for s in range(20)] + [np.array([2, 7, 11])]     # single samples and one group
    held = mc.approximate_loo(lin, folds[:20]).raw
    for fold in folds:
        out = np.isin(np.arange(len(y)) // 3, fold)
        A = np.vstack([X[~out], P])
        b = np.concatenate([y[~out], np.zeros(len(P))])
        theta = np.linalg.lstsq(A, b, rcond=None)[0]
        brute = X[out] @ theta - y[out]
        got = held[out] if len(fold) == 1 else mc.approximate_loo(lin, [fold]).raw[out]
        np.testing.assert_allclose(got, brute, rtol=1e-9, atol=1e-12)


def test_approximate_loo_names_a_fold_that_leaves_a_parameter_without_data():
    rng = np.random.default_rng(4)
    lin, *_ = _linear_case(rng, n_samples=6, n_par=3, prior_cols=())
    lin.J[lin.data & (lin.sample != 0), 2] = 0.0          # only sample 0 sees parameter 2
    held = mc.approximate_loo(lin)
    assert held.undetermined == [0]
    assert np.all(np.isnan(held.raw[lin.sample[lin.data] == 0]))
    assert np.all(np.isfinite(held.raw[lin.sample[lin.data] != 0]))


def test_approximate_loo_of_a_calibration_matches_brute_force_leave_one_out(tmp_path):
    # UR5, 30 postures, 50 um noise, full geometric model (the structurally dependent placements fixed by the
    # selection). Each refit moves the parameters by about sigma / sqrt(n) around a nominal within 0.5 mm /
    # 0.5 mrad, so the second-order terms the linearisation ignores are far below a micrometre: the closed form
    # must give every held-out point error within 1 um of the refit's.
    cfg, _, values = write_case(tmp_path, np.random.default_rng(5), n=30)
    setup = setup_for_data(cfg)
    setup.options.regularisation = "none"
    calibrate(setup.problem, setup.options)
    lin = mc.linearise(setup.problem)
    _, approx = mc.norms(lin, mc.approximate_loo(lin).raw)
    fresh = setup_for_data(cfg)
    fresh.options.regularisation = "none"
    cv = cross_validate(fresh.problem, kfold(30, 30), fresh.options)
    brute = np.linalg.norm(cv.blocks["tracker"].points()[:, 0], axis=1) * 1e3
    np.testing.assert_allclose(approx, brute, atol=1e-3)
    assert mc.rms(approx) > 1.2 * mc.rms(mc.norms(lin, lin.r[lin.data] / lin.scale[lin.data])[1])   # held out > fit


def _restricted_logpdf(J, y, sigma, s2):
    """Brute force: the density of y's component orthogonal to the flat columns, from the dense covariance."""
    flat = ~np.isfinite(sigma)
    Q = scipy.linalg.null_space(J[:, flat].T)             # orthonormal basis of the complement
    A = J[:, ~flat] * sigma[~flat]
    C = s2 * np.eye(len(y)) + A @ A.T
    return scipy.stats.multivariate_normal(np.zeros(Q.shape[1]), Q.T @ C @ Q).logpdf(Q.T @ y)


def test_log_evidence_equals_the_dense_gaussian_density_and_its_noise_maximises_it():
    rng = np.random.default_rng(6)
    J = rng.normal(size=(15, 5))
    sigma = np.array([np.inf, 0.3, 2.0, 0.7, np.inf])      # two flat columns (registration), three with priors
    y = J @ np.where(np.isfinite(sigma), rng.normal(size=5) * np.where(np.isfinite(sigma), sigma, 0), 3.0) \
        + rng.normal(0, 0.5, 15)
    for s2 in (0.1, 0.25, 2.0):
        assert mc.log_evidence(J, y, sigma, noise2=s2).log_evidence == pytest.approx(
            _restricted_logpdf(J, y, sigma, s2), abs=1e-9)
    best = mc.log_evidence(J, y, sigma)
    grid = np.exp(np.linspace(np.log(best.noise2) - 1, np.log(best.noise2) + 1, 2001))
    dense = [_restricted_logpdf(J, y, sigma, s2) for s2 in grid]
    assert best.log_evidence >= max(dense) - 1e-9
    assert best.noise2 == pytest.approx(grid[int(np.argmax(dense))], rel=2e-3)
    assert best.flat_rank == 2
    # more prior columns than the data have dimensions left: still the dense density
    wide = rng.normal(size=(6, 9))
    sw = np.r_[np.inf, np.full(8, 0.5)]
    yw = rng.normal(size=6)
    assert mc.log_evidence(wide, yw, sw, noise2=0.3).log_evidence == pytest.approx(
        _restricted_logpdf(wide, yw, sw, 0.3), abs=1e-9)


def test_log_evidence_recovers_the_simulated_noise_level():
    # y = J d + e with d from its prior and e of variance 4: the maximising noise variance is within four of its
    # standard errors (about sqrt(2 / m) relative, m = 2000 rows) of 4
    rng = np.random.default_rng(7)
    m = 2000
    J = rng.normal(size=(m, 6))
    sigma = np.array([np.inf, np.inf, 1.0, 1.0, 0.2, 5.0])
    d = np.where(np.isfinite(sigma), rng.normal(size=6) * np.where(np.isfinite(sigma), sigma, 0), 10.0)
    y = J @ d + rng.normal(0, 2.0, m)
    assert mc.log_evidence(J, y, sigma).noise2 == pytest.approx(4.0, rel=4 * np.sqrt(2 / m))


def test_final_prediction_error_predicts_the_error_at_the_same_postures_with_new_noise():
    # ordinary least squares at fixed X: E[new-noise mean square] / E[training mean square] = (m + p) / (m - p);
    # 4000 replications put the Monte Carlo ratio within about 1 % of it (tolerance 3 %)
    rng = np.random.default_rng(8)
    lin, X, y, _ = _linear_case(rng, n_samples=10, n_par=8, prior_cols=())
    crit = mc.information_criteria(lin)
    assert crit.parameters == pytest.approx(8.0, abs=1e-9)
    H = X @ np.linalg.pinv(X)
    train, new = [], []
    for _ in range(4000):
        e = rng.normal(size=len(y))
        fit = H @ e
        train.append(np.mean((fit - e) ** 2))
        new.append(np.mean((fit - rng.normal(size=len(y))) ** 2))
    assert np.mean(new) / np.mean(train) == pytest.approx(crit.fpe, rel=0.03)
    # a prior shrinks the effective number of parameters below the count
    shrunk, *_ = _linear_case(np.random.default_rng(8), n_samples=10, n_par=8, prior_cols=(5, 6, 7),
                              prior_sigma=0.05)
    assert 5.0 < mc.information_criteria(shrunk).parameters < 7.0


@pytest.mark.parametrize("c", [4e-5, 0.0])
def test_nominal_evidence_prefers_compliance_only_when_the_robot_has_it(tmp_path, c):
    # a UR5 whose shoulder and elbow bend by 1-2 mrad under gravity (c = 4e-5 rad/(N m), about 1 mm at the
    # flange, 20 times the noise) or not at all; the evidence of the model with compliance must win by far in
    # the first case, and gain at most 2 nats (the chance gain of two unneeded parameters) in the second
    comp = {"shoulder_lift_joint": c, "elbow_joint": c}
    cfg, _, _ = write_case(tmp_path, np.random.default_rng(9), n=36, compliance=comp,
                           parameters={"compliance": list(comp)})
    with_c = mc.nominal_evidence(setup_for_data(cfg).problem)
    without = mc.nominal_evidence(setup_for_data(cfg, parameters={"compliance": False}).problem)
    assert with_c.flat_rank == without.flat_rank
    if c:
        assert with_c.log_evidence > without.log_evidence + 50
        assert with_c.noise2 < 4.0                           # stated sigma 50 um: the model explains the data
    else:
        assert with_c.log_evidence < without.log_evidence + 2.0
        assert without.noise2 == pytest.approx(1.0, rel=0.3)   # 108 rows: the noise is estimated to ~15 %
    assert SIGMA == 5e-5
