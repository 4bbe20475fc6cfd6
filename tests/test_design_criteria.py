"""Information criteria: closed-form values, and the block-update scores against direct evaluation."""
import numpy as np
import pytest

from robocal.design import criteria as dc


def test_criteria_on_known_singular_values():
    sig = np.array([4.0, 2.0, 0.5])          # singular values of J; M = diag(sig^2)
    M, m = np.diag(sig ** 2), 12
    v = dc.all_criteria(M, m, W=np.diag([1.0, 0.0, 0.0]))
    assert v["D"] == pytest.approx(np.log(16 * 4 * 0.25))
    assert v["E"] == pytest.approx(0.5) and v["O3"] == pytest.approx(0.5)
    assert v["A"] == pytest.approx(-(1 / 16 + 1 / 4 + 1 / 0.25))
    assert v["I"] == pytest.approx(-1 / 16)
    assert v["O1"] == pytest.approx((4 * 2 * 0.5) ** (1 / 3) / np.sqrt(12))
    assert v["O2"] == pytest.approx(0.5 / 4)
    assert v["O4"] == pytest.approx(0.25 / 4)
    assert v["O5"] == pytest.approx(1 / (1 / 4 + 1 / 2 + 2))


def test_singular_information_scores_worst():
    M = np.diag([1.0, 1.0, 0.0])
    v = dc.all_criteria(M, 3)
    assert v["D"] == -np.inf and v["A"] == -np.inf
    assert v["E"] == 0 and v["O2"] == 0 and v["O4"] == 0 and v["O5"] == 0 and v["O1"] == 0


@pytest.mark.parametrize("criterion", dc.CRITERIA)
def test_block_update_scores_equal_direct_evaluation(criterion):
    rng = np.random.default_rng(0)
    L, d, K = 7, 3, 25
    A = rng.normal(size=(20, L))
    M = A.T @ A
    B = rng.normal(size=(K, d, L))
    B[3, 2] = 0.0                                # a padded block (2 true rows)
    rows = np.full(K, d)
    rows[3] = 2
    W = rng.normal(size=(L, L))
    W = W @ W.T
    got = dc.scores_after_adding(criterion, M, 20, B, rows, W)
    want = [dc.evaluate(criterion, M + B[k].T @ B[k], 20 + rows[k], W) for k in range(K)]
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)


def test_unknown_criterion_is_refused():
    with pytest.raises(ValueError, match="unknown criterion 'X'"):
        dc.from_eigenvalues("X", np.ones(3), 3)


@pytest.mark.parametrize("criterion", ["E", "O2", "O3", "O4", "O5", "D", "O1"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_pruned_best_addition_equals_full_argmax(criterion, seed):
    rng = np.random.default_rng(seed)
    L, d, K = 9, 4, 300
    A = rng.normal(size=(30, L)) * rng.uniform(0.1, 3, L)   # uneven spectrum
    M = A.T @ A
    B = rng.normal(size=(K, d, L)) * rng.uniform(0.01, 1, (K, 1, 1))
    B[::7] = B[3]                                           # exact ties: the lowest index must win
    rows = np.full(K, d)
    full = dc.scores_after_adding(criterion, M, 30, B, rows)
    k, value = dc.best_addition(criterion, M, 30, B, rows)
    assert k == int(np.argmax(full)) and value == pytest.approx(full.max(), rel=1e-12)
