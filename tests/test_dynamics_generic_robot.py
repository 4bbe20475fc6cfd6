"""`robocal identify` on a robot other than the TIAGo: a UR5 log (every joint recorded, no gear ratio, irregular
time steps) written as CSV files and read through a config alone. The OLS base parameters come back within
their reported standard errors, every body of the consistent model is realisable, and the consistent fit
does not fit the training window better than the unconstrained one (which would mean OLS did not minimise
its own objective)."""
import numpy as np
from scipy.stats import chi2

from robocal.dynamics.identification import base_values_of
from robocal.workflows.identify_summary import body_mass_lines, findings
from robocal.workflows.identify import identify_from_config
from robocal.dynamics.inertial import parameter_vector
from ur5_dynamics_cases import write_ur5_log


def test_ur5_log_through_a_config(tmp_path):
    path, truth, extra = write_ur5_log(tmp_path)
    res = identify_from_config(path)
    sel = res.ols.selection
    beta_true = base_values_of(sel, np.r_[parameter_vector(truth), extra])
    z = (res.ols.values - beta_true) / res.ols.std
    assert np.sum(z**2) < chi2.ppf(0.999, sel.rank), (np.sum(z**2), sel.rank)
    z_cad = (base_values_of(sel, np.r_[parameter_vector(res.model), np.zeros(extra.size)]) - beta_true) / res.ols.std
    assert np.sum(z_cad**2) > 100 * chi2.ppf(0.999, sel.rank)      # the test can fail
    assert all(ok for _, ok in res.consistency.values())
    assert res.within_noise["residual_increase_independent_rows"] >= -1e-6
    cad, ols = (np.array(res.validation[m]["rmse"]) for m in ("cad", "ols"))
    assert np.all(ols < cad)
    # a physical log: the default rule finds a prior weight within the noise of the constrained fit, the fit
    # lies within the unconstrained fit's noise too, and the masses stay near the CAD ones (no NOTE, no finding)
    assert res.prior.rule == "within_bounds_noise" and res.prior.attained
    assert res.within_noise["distance_in_noise_units"] <= res.within_noise["chi2_95"]
    assert not any(line.startswith("NOTE") for line in body_mass_lines(res))
    assert findings(res) == []


def test_the_command_prints_the_summary_it_wrote(tmp_path, capsys):
    from robocal.cli.main import main
    path, _, _ = write_ur5_log(tmp_path)
    out = tmp_path / "out"
    assert main(["identify", str(path), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("Dynamic identification") and (out / "summary.txt").read_text() in printed
    assert (out / "ur5_robot_identified.urdf").is_file()
