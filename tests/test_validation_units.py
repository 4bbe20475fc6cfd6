"""Building blocks of issue 18 on linear synthetic truth: the evidence's prior strength and noise level, the
determinacy classes, the one-standard-error rule, the honest block statistics."""
import numpy as np
import pytest

from robocal.estimation.determinacy import DETERMINED, NOT_DETERMINED, WEAK, classify
from robocal.estimation.model_selection import one_standard_error
from robocal.estimation.regularisation import choose_strength
from robocal.estimation.result import term_norms


def test_evidence_recovers_the_prior_strength_and_the_noise_of_a_linear_gaussian_model():
    rng = np.random.default_rng(7)
    m, n, n_flat = 3000, 60, 4
    J = rng.normal(size=(m, n + n_flat)) * 0.5
    scales = np.r_[np.full(n, 2.0), np.full(n_flat, np.inf)]
    lam, noise = 0.3, 1.5
    d = np.r_[rng.normal(0, lam * 2.0, n), rng.normal(0, 100.0, n_flat)]    # flat columns: anything
    r = J @ d + rng.normal(0, noise, m)
    ev = choose_strength(J, r, scales)
    # 60 draws fix lam to about 1/sqrt(2 * 60) ~ 9 % (one sigma); the grid steps by 26 %: within 40 %
    assert ev.strength == pytest.approx(lam, rel=0.4)
    # 3000 rows fix the noise variance to sqrt(2 / 3000) ~ 2.6 %: within 10 %
    assert ev.noise2 == pytest.approx(noise ** 2, rel=0.1)
    assert np.all(np.isinf(ev.stderr[n:])) and np.all(np.isfinite(ev.stderr[:n]))


def test_classes_against_threshold_and_scale_and_the_weak_direction_in_words():
    # three parameters: one seen strongly, one weakly, and a pair whose difference the data never see
    J = np.array([[1e5, 0, 0, 0], [0, 50.0, 0, 0], [0, 0, 1.0, 1.0], [0, 0, 1.0, 1.0]])
    names = ["a", "b", "c", "d"]
    thresholds = np.full(4, 1e-4)
    det = classify(names, J, 1.0, thresholds, np.full(4, 1e-2), ["e"], with_prior={"c", "d"})
    # se(a) = 1e-5 < 1e-4; se(b) = 0.02 > scale 0.01 -> not determined; c, d: no information
    assert det.classes["a"] == DETERMINED and det.classes["b"] == NOT_DETERMINED
    assert det.classes["c"] == NOT_DETERMINED and det.classes["e"] == NOT_DETERMINED
    det2 = classify(names[:2], J[:2, :2], 1.0, thresholds[:2], np.array([1e-2, 1.0]), [], set())
    assert det2.classes["b"] == WEAK                      # 0.02 below a scale of 1
    null = det.directions[0]
    assert {n for n, _ in null.terms} == {"c", "d"} and null.decided_by_prior
    assert "the prior decided it" in null.describe()


def test_one_standard_error_rule_keeps_the_simplest_model_within_reach_of_the_best():
    assert one_standard_error(np.array([3.0, 2.1, 2.0, 2.05]), np.array([0.2, 0.2, 0.15, 0.3])) == (1, 2)
    assert one_standard_error(np.array([3.0, 2.5, 2.0]), np.array([0.1, 0.1, 0.1])) == (2, 2)


def test_term_norms_are_3d_norms_of_each_point_and_absolute_values_of_single_rows():
    raw = np.array([3.0, 4.0, 0.0, 0.0, 0.0, 2.0, 1.0])
    units = np.array(["length"] * 6 + ["length"])
    group = np.array([0, 0, 0, 1, 1, 1, 2])
    norms, triples = term_norms(raw[:6], units[:6], group[:6], "length")
    assert norms.tolist() == [5.0, 2.0] and triples
    norms, triples = term_norms(raw, units, group, "length")
    assert norms.tolist() == [5.0, 2.0, 1.0] and not triples
