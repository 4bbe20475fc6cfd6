"""How strongly the CAD values pull the consistent fit: the prior weight lambda, chosen from the data.

Three rules (the config's model.prior_rule):
  within_bounds_noise (default): the largest lambda of the grid whose fit stays within the noise of the
      fit at the grid's weakest lambda under the same constraints (physical and plausibility bounds):
      the same discrepancy test, measured from what the constraints alone already cost instead of from
      the unconstrained fit. When the constraints cost more than the noise (a finding in itself, reported
      by constraint_cost.py), within_noise can only take the weakest prior, which leaves every direction
      the data do not determine free to drift between windows; this rule still pulls those to CAD.
  within_noise: the largest lambda of the grid whose consistent fit stays within the
      unconstrained fit's noise on the training window (the squared distance of its base parameters
      from the OLS estimate, in noise units, at most the chi-square 95 % quantile for the number of
      base parameters): as much CAD as the data's noise allows (the discrepancy principle). The distance
      grows with lambda; when even the weakest prior of the grid lies beyond the noise (the physical
      constraints alone cost more), that weakest one is taken and the summary says so.
  holdout: fit on the first part of the training window less the filter's reach, score the weighted
      torque error on the rest, keep the best weight (ties: the larger one).
The first follows the issue's definition of a consistent fit (within the data's noise of the
unconstrained one) and uses the whole training window; the second asks which weight predicts best,
from a shorter window.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.dynamics.consistent_fit import fit_consistent
from robocal.dynamics.regression import Regressor

RULES = ("within_bounds_noise", "within_noise", "holdout")
DEFAULT_GRID = tuple(10.0 ** np.arange(-4, 2.01, 0.5))     # half-decade steps


@dataclass
class PriorWeightChoice:
    """rule (RULES); grid of lambda values; scores per value: the squared distance from OLS in noise units
    (within_noise) or the weighted mean-square torque error on the scored part (holdout); chosen lambda;
    bound: the chi-square quantile the distance must not exceed (within_noise); attained: some weight
    met that bound; split_fraction: the fitted share of the training window (holdout); gap_s: the time
    between the last fitted and the first scored sample (holdout; identify_run leaves the filter's reach)."""

    rule: str
    grid: list[float]
    scores: list[float]
    chosen: float
    bound: float = float("nan")
    attained: bool = True
    split_fraction: float = 1.0
    gap_s: float = 0.0


def within_noise_choice(reg: Regressor, tau: np.ndarray, sigma: np.ndarray, cad: np.ndarray, grid,
                        rss_ols: float | None, noise_unit: float, bound: float, bounds=None,
                        fits: dict | None = None) -> PriorWeightChoice:
    """The largest lambda whose fit's weighted data cost exceeds the reference by at most bound noise units
    (noise_unit: weighted cost per unit); else the smallest lambda. Reference: the unconstrained fit's cost
    rss_ols (rule within_noise), or with rss_ols None the weakest lambda's fit (within_bounds_noise).
    bounds: the plausibility rows (plausible_bounds.LinearBounds) every fit keeps; fits: a dict that receives
    each lambda's fit (the caller's fit at the chosen or the weakest lambda is one of them: not solved twice)."""
    ordered = sorted(float(g) for g in grid)
    fitted = {lam: fit_consistent(reg, tau, sigma, cad, lam, bounds=bounds) for lam in ordered}
    if fits is not None:
        fits.update(fitted)
    costs = [fitted[lam].data_cost for lam in ordered]
    rule = "within_noise" if rss_ols is not None else "within_bounds_noise"
    reference = rss_ols if rss_ols is not None else costs[0]
    distance = [(c - reference) / noise_unit for c in costs]
    inside = [lam for lam, d in zip(ordered, distance) if d <= bound]
    chosen = max(inside) if inside else ordered[0]
    return PriorWeightChoice(rule, ordered, distance, chosen, float(bound), bool(inside))


def holdout_choice(reg_fit: Regressor, tau_fit: np.ndarray, reg_check: Regressor, tau_check: np.ndarray,
                   sigma: np.ndarray, cad: np.ndarray, grid, split_fraction: float, bounds=None) -> PriorWeightChoice:
    """Fit on (reg_fit, tau_fit), score on (reg_check, tau_check) for each lambda of `grid`; ties go
    to the larger lambda (closer to CAD)."""
    scores = {}
    for lam in grid:
        fit = fit_consistent(reg_fit, tau_fit, sigma, cad, lam, bounds=bounds)
        err = (fit.predict(reg_check) - tau_check) / sigma
        scores[float(lam)] = float(np.mean(err**2))
    best = min(scores.values())
    chosen = max(lam for lam, s in scores.items() if s <= best * (1 + 1e-9))
    ordered = sorted(scores)
    return PriorWeightChoice("holdout", ordered, [scores[k] for k in ordered], chosen,
                             split_fraction=split_fraction)
