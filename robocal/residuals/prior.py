"""Prior on parameters: (value - prior_mean) / prior_sigma for every parameter that has a prior.

This is the one residual that looks at parameters rather than frames; the problem layer calls it
with the parameter set. Priors carry their unit (metres and radians are never mixed in one scale).
"""
from __future__ import annotations

import numpy as np

from robocal.model.parameters import ParameterSet


def prior_rows(params: ParameterSet) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(r, J, names): one row per parameter with a prior; J has one column per free parameter."""
    free = params.free_names
    col = {n: i for i, n in enumerate(free)}
    with_prior = [p for p in params if p.prior_sigma is not None and p.vary]
    r = np.array([(p.value - p.prior_mean) / p.prior_sigma for p in with_prior])
    J = np.zeros((len(with_prior), len(free)))
    for k, p in enumerate(with_prior):
        J[k, col[p.name]] = 1.0 / p.prior_sigma
    return r, J, [p.name for p in with_prior]
