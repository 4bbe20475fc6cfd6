"""Synthetic truth for the whole config path (CSV files, resampling, filtering, decimation,
regressor, OLS base parameters) on a simulated TIAGo trajectory with the shipped log's irregular
time stamps and its noise levels (positions and efforts)."""
import numpy as np
from scipy.stats import chi2

from robocal.dynamics.identification import base_values_of
from robocal.workflows.identify import identify_from_config
from robocal.dynamics.inertial import parameter_vector
from tiago_dynamics_cases import synthetic_log


def test_whole_path_recovers_base_parameters_within_noise(tmp_path):
    cfg, truth, extra = synthetic_log(tmp_path, rows=4000, train=(2.0, 30.0), validate=(30.0, 39.0))
    cfg["model"]["prior_grid"] = [1.0]      # the consistent fit is not under test here
    cfg["model"]["candidate_terms"] = []    # nor the term search (tests/test_dynamics_terms.py)
    res = identify_from_config(cfg, tmp_path)
    sel = res.ols.selection
    true_full = np.r_[parameter_vector(truth), extra.reshape(-1)]
    beta_true = base_values_of(sel, true_full)
    z = (res.ols.values - beta_true) / res.ols.std
    # the standard errors allow for the filtered noise's correlation across decimated samples
    # (serial_correlation.py; without it sum z^2 is 156); with correct standard errors, sum z^2 ~ chi-square(rank): its 99.9 % quantile bounds it, and
    # no single |z| exceeds 4.5 (two-sided 7e-6 each, < 0.05 % over the ~60 parameters)
    assert np.sum(z**2) < chi2.ppf(0.999, sel.rank), (np.sum(z**2), sel.rank)
    assert np.max(np.abs(z)) < 4.5
    # the tolerance is not vacuous: the CAD model (the truth without its 0.1-0.3 kg point masses and
    # without friction) fails the same test by far
    cad_full = np.r_[parameter_vector(res.model), np.zeros(extra.size)]
    z_cad = (base_values_of(sel, cad_full) - beta_true) / res.ols.std
    assert np.sum(z_cad**2) > 100 * chi2.ppf(0.999, sel.rank)
