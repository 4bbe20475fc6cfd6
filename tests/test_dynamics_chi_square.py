"""robocal.dynamics.chi_square: the identification's chi-square quantiles are scipy.stats.chi2.ppf's numbers."""
from scipy.stats import chi2

from robocal.dynamics.chi_square import chi2_quantile


def test_chi2_quantile_is_scipy_stats_ppf_exactly():
    # the levels the identification uses: 95 %, Bonferroni 5 % over a few to a few hundred tests
    for q in (0.95, 1 - 0.05 / 4, 1 - 0.05 / 123, 1 - 0.05 / 600, 0.999):
        for dof in (1, 2, 5, 61, 63, 100.0):
            assert chi2_quantile(q, dof) == float(chi2.ppf(q, dof)), (q, dof)
