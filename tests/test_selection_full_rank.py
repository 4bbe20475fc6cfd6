"""The base-parameter selection's shortcut for full-rank columns (issue 37): when the column-scaled matrix is
well within the rank tolerance, every column is kept without the walk; the result must be the walk's. A plain
walk (Gram-Schmidt twice, each column against the kept ones) is the reference here."""
import numpy as np
import pytest

from robocal.estimation.identifiability import select_base_parameters


def _walk(J, rtol):
    norms = np.linalg.norm(J, axis=0)
    W = J / norms
    kept, basis = [], np.zeros((J.shape[0], 0))
    for j in range(J.shape[1]):
        q = W[:, j] - basis @ (basis.T @ W[:, j])
        q -= basis @ (basis.T @ q)
        if np.linalg.norm(q) > rtol:
            basis = np.column_stack([basis, q / np.linalg.norm(q)])
            kept.append(j)
    return kept


@pytest.mark.parametrize("rows, cols, condition", [(60, 20, 1e2), (20, 20, 1e5), (40, 31, 1e7), (30, 30, 5e7),
                                                   (12, 30, 1e2)])
def test_full_rank_columns_are_all_kept_as_the_walk_keeps_them(rows, cols, condition):
    rng = np.random.default_rng(cols)
    U, _ = np.linalg.qr(rng.normal(size=(rows, min(rows, cols))))
    V, _ = np.linalg.qr(rng.normal(size=(cols, cols)))
    s = np.logspace(0, -np.log10(condition), min(rows, cols))
    J = (U * s) @ V[:, :min(rows, cols)].T * rng.uniform(0.1, 10, cols)      # columns of different scales
    sel = select_base_parameters(J, rtol=1e-8)
    assert sel.independent == _walk(J, 1e-8)
    if rows >= cols:
        assert sel.dependent == [] and sel.regrouping.shape == (cols, 0)
        W = J / np.linalg.norm(J, axis=0)
        sv = np.linalg.svd(W, compute_uv=False)
        assert sel.condition == pytest.approx(sv[0] / sv[-1], rel=1e-9)
        assert np.allclose(sel.singular_values, sv, rtol=1e-12)


def test_a_repeated_column_still_takes_the_walk():
    rng = np.random.default_rng(5)
    J = rng.normal(size=(50, 8))
    J[:, 6] = 3.0 * J[:, 2]
    sel = select_base_parameters(J, rtol=1e-8)
    assert sel.dependent == [6] and sel.confounded_with(6)[0][0] == "p2"
    assert sel.confounded_with(6)[0][1] == pytest.approx(3.0, rel=1e-12)
