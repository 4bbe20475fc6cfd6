"""The unconstrained fit minimises the objective it reports (its weights are the ones it returns), so the
consistent fit, which uses those weights, can never beat it on the training window; and the report says
when the chosen prior weight sits at the end of the grid."""
import numpy as np

from robocal.dynamics.prior_weight import PriorWeightChoice
from robocal.workflows.identify_summary import grid_edge_note, within_noise_verdict
from robocal.dynamics.regression import Regressor, fit_base, row_weights


def heteroscedastic_case(seed=0, samples=400):
    """Two recorded joints whose noise differs by 50x, six columns (the last a copy: one dependent)."""
    rng = np.random.default_rng(seed)
    nr = 2
    X = rng.normal(size=(samples * nr, 5))
    X = np.column_stack([X, X[:, 0] + X[:, 1]])
    beta = rng.normal(size=6)
    noise = np.tile([0.01, 0.5], samples) * rng.normal(size=samples * nr)
    tau = (X @ beta + noise).reshape(samples, nr)
    names = [f"p{i}" for i in range(6)]
    return Regressor(X, names, 6, [0, 1]), tau


def test_the_fit_minimises_the_objective_weighted_by_the_sigma_it_returns():
    reg, tau = heteroscedastic_case()
    fit = fit_base(reg, tau)
    w = row_weights(fit.sigma, len(tau))
    Xb = reg.X[:, fit.selection.independent] * w[:, None]
    gradient = Xb.T @ (tau.reshape(-1) * w - Xb @ fit.values)
    # zero to rounding: relative to the size of the terms it sums
    scale = np.abs(Xb).T @ np.abs(tau.reshape(-1) * w)
    assert np.max(np.abs(gradient) / scale) < 1e-10
    # and the weights are the residual RMS per joint of a fit, of the noise's size
    assert 0.5 * 0.01 < fit.sigma[0] < 2 * 0.01 and 0.5 * 0.5 < fit.sigma[1] < 2 * 0.5


def test_grid_edge_note_names_the_edge():
    grid = [0.1, 1.0, 10.0]
    assert "largest" in grid_edge_note(PriorWeightChoice("holdout", grid, [3, 2, 1], 10.0, split_fraction=0.75))
    assert "smallest" in grid_edge_note(PriorWeightChoice("holdout", grid, [1, 2, 3], 0.1, split_fraction=0.75))
    assert grid_edge_note(PriorWeightChoice("holdout", grid, [2, 1, 2], 1.0, split_fraction=0.75)) == ""
    # within-noise rule: the weakest weight because none met the bound is said as such
    missed = grid_edge_note(PriorWeightChoice("within_noise", grid, [90, 95, 120], 0.1, bound=80.0, attained=False))
    assert "no weight of the grid meets that bound" in missed and "90 > 80" in missed
    assert grid_edge_note(PriorWeightChoice("within_noise", grid, [10, 50, 90], 1.0, bound=80.0)) == ""


def test_within_noise_verdict_follows_the_quantile():
    assert within_noise_verdict({"distance_in_noise_units": 70.0, "chi2_95": 80.2}).startswith("The consistent")
    assert within_noise_verdict({"distance_in_noise_units": 93.2, "chi2_95": 80.2}).startswith("NOTE")
