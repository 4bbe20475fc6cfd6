"""prior_weight.py's within-noise rule: the strongest CAD prior whose fit stays within the unconstrained
fit's noise, on a synthetic truth whose CAD values are wrong."""
import numpy as np
from scipy.stats import chi2

from robocal.dynamics.prior_weight import within_noise_choice
from test_dynamics_constraint_cost import NOISE, bodies, synthetic


# the random regressor is far more informative than a robot's (unit columns, noise 0.01): its prior needs
# larger weights than GRID to matter
GRID = tuple(10.0 ** np.arange(0, 8.01, 0.5))


def case():
    rng = np.random.default_rng(5)
    truth = np.r_[bodies(rng), 0.2, 0.4, 0.3]
    reg, tau = synthetic(truth, seed=5)
    cad = truth[:20] * 1.5                        # a CAD model 50 % off: a strong prior pulls the fit away
    w = 1.0 / NOISE
    x, *_ = np.linalg.lstsq(reg.X * w, tau[:, 0] * w, rcond=None)
    rss = float(np.sum((reg.X @ x * w - tau[:, 0] * w) ** 2))
    dof = len(tau) - reg.X.shape[1]
    return reg, tau, cad, rss, rss / dof


def test_the_strongest_prior_within_the_bound_is_chosen():
    reg, tau, cad, rss, unit = case()
    bound = chi2.ppf(0.95, reg.X.shape[1])
    choice = within_noise_choice(reg, tau, np.array([NOISE]), cad, GRID, rss, unit, bound)
    d = np.array(choice.scores)
    assert np.all(np.diff(d) >= -1e-6 * bound)                  # the distance grows with the weight
    assert d[0] < bound < d[-1]                                  # this case has both sides on the grid
    k = choice.grid.index(choice.chosen)
    assert choice.attained and d[k] <= bound and d[k + 1] > bound
    assert d[0] >= -1e-6                                          # never below the unconstrained fit


def test_no_weight_within_the_bound_takes_the_weakest():
    reg, tau, cad, rss, unit = case()
    choice = within_noise_choice(reg, tau, np.array([NOISE]), cad, GRID, rss, unit, bound=-1.0)
    assert not choice.attained and choice.chosen == min(GRID)


def test_the_bounds_rule_measures_from_the_weakest_constrained_fit():
    """within_bounds_noise (rss_ols None): the distance is measured from the weakest weight's fit under the
    same constraints, so it starts at zero, and the chosen weight is the strongest within the bound."""
    reg, tau, cad, rss, unit = case()
    bound = chi2.ppf(0.95, reg.X.shape[1])
    choice = within_noise_choice(reg, tau, np.array([NOISE]), cad, GRID, None, unit, bound)
    d = np.array(choice.scores)
    assert choice.rule == "within_bounds_noise" and d[0] == 0.0
    k = choice.grid.index(choice.chosen)
    assert d[k] <= bound and (k == len(d) - 1 or d[k + 1] > bound)
    from_ols = within_noise_choice(reg, tau, np.array([NOISE]), cad, GRID, rss, unit, bound)
    assert choice.chosen >= from_ols.chosen           # never a weaker prior than the rule measured from OLS
