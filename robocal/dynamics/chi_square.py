"""The chi-square quantile the identification's tests use, from scipy.special.

scipy.stats.chi2.ppf(q, k) is computed as 2 gammaincinv(k / 2, q) (the same number); scipy.stats builds its
hundred distributions at import (0.2-0.3 s of CPU), for this one function.
"""
from __future__ import annotations

from scipy.special import gammaincinv


def chi2_quantile(q: float, dof: float) -> float:
    """The q quantile of the chi-square distribution with `dof` degrees of freedom (scipy.stats.chi2.ppf)."""
    return float(2.0 * gammaincinv(dof / 2.0, q))
