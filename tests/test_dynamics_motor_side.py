"""Motor-side identification (docs/dynamics_motors.md): simulated 5 kHz logs of motor encoders (quantised) and
motor currents (white noise) through a coupled transmission, identified from the example's config alone.

Both couplings of examples/motor_dynamics/ (a UR5 whose joint 6 is driven by motors 5 and 6, a TIAGo arm with a
differential wrist): the OLS base parameters lie within 3 standard errors of the truth's, the motors' friction
and rotor inertias are recovered, and the same logs identified with the coupling left out of the transmission
miss the truth by far more than the noise allows. `robocal evaluate` predicts the second session per motor at
the current noise and reports per-joint errors."""
import json

import numpy as np
import pytest
import yaml
from scipy.stats import chi2

from motor_dynamics_cases import CASES, base_z, write_case
from robocal.cli.main import main
from robocal.dynamics.transmission import Transmission
from robocal.workflows.identify import identify_from_config
from robocal.workflows.identify_outputs import write_identification

CURRENT_NOISE = 0.02        # A: make_logs.CURRENT_NOISE


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    """Each case's configs and logs, written once by the example's script; and its identification."""
    out = {}
    for case in CASES:
        config, truth = write_case(case, tmp_path_factory.mktemp(case))
        out[case] = (config, truth, identify_from_config(config))
    return out


@pytest.mark.parametrize("case", CASES)
def test_the_truth_is_recovered_within_its_standard_errors(cases, case):
    config, truth, res = cases[case]
    assert res.channels.motors and res.recorded == truth.config.transmission.motors
    assert res.processed.choices[0].startswith("log rate 5000 Hz reduced by 20 to 250 Hz")
    z = base_z(res, truth)
    rank = res.ols.selection.rank
    # the standard errors allow for the filtered noise's correlation (serial_correlation.py): the sum of squared
    # z follows chi-square(rank) when they are right and the model is the truth's; the bar is every base
    # parameter within 3 of them (for ~60 independent z, one beyond 3 has a ~15 % chance: seed 0, the first tried)
    assert np.sum(z ** 2) < chi2.ppf(0.999, rank), (np.sum(z ** 2), rank)
    assert np.all(np.abs(z) < 3), dict(zip(res.ols.names, np.round(z, 2)))
    # the motors' friction and rotor inertias: each a base parameter on its own except a rotor inertia that
    # turns with a body's inertia about the same axis (the first motors': said in the selection), all recovered
    alone = {n: zz for n, zz in zip(res.ols.names, z) if n.split(".")[0] in res.recorded}
    for motor in res.recorded:
        assert {f"{motor}.coulomb", f"{motor}.viscous", f"{motor}.offset"} <= set(alone)
    merged = [f"{m}.armature" for m in res.recorded if f"{m}.armature" not in alone]
    dropped = " ".join(res.ols.selection.describe())
    assert all(f"{name} cannot be separated" in dropped for name in merged), merged
    assert len(merged) <= 2 and f"{res.recorded[-1]}.armature" in alone
    # the plausible fit carries them too, non-negative, and stays within the unconstrained fit's noise (its CAD
    # prior pulls the inertias, and through them the motors' terms: its own figures are not held to the truth)
    extra = dict(zip(res.consistent_extra_names(), res.consistent.extra))
    assert all(extra[f"{m}.{k}"] >= 0 for m in res.recorded for k in ("coulomb", "viscous", "armature"))
    assert res.within_noise["distance_in_noise_units"] <= res.within_noise["chi2_95"]


@pytest.mark.parametrize("case", CASES)
def test_leaving_the_coupling_out_is_caught(cases, case, tmp_path):
    config, truth, res = cases[case]
    cfg = yaml.safe_load(config.read_text())
    tr = cfg["transmission"]
    if "coupling" in tr:                       # the UR5: joint 6 from motor 6 alone
        tr.pop("coupling")
        coupled = ["motor_5"]
    else:                                      # the wrist: each of arm_6, arm_7 from its own motor alone
        tr["matrix"]["arm_6_joint"] = {"m6": -0.5}
        tr["matrix"]["arm_7_joint"] = {"m7": 0.5}
        coupled = ["m6", "m7"]
    wrong = identify_from_config(cfg, config.parent)
    z = base_z(wrong, truth)
    assert np.sum(z ** 2) > chi2.ppf(0.999, wrong.ols.selection.rank)
    for motor in coupled:                      # the coupled motors' rows are not explained
        k = res.recorded.index(motor)
        assert wrong.ols.sigma[k] > 3 * res.ols.sigma[k], (motor, wrong.ols.sigma[k], res.ols.sigma[k])


@pytest.mark.parametrize("case", CASES)
def test_a_second_session_is_predicted_per_motor_and_per_joint(cases, case, tmp_path, capsys):
    config, truth, res = cases[case]
    out = tmp_path / "out"
    write_identification(res, out)             # what `robocal identify` writes (its CLI: the tests below)
    side = yaml.safe_load((out / "dynamics.yaml").read_text())
    assert Transmission.from_dict(side["transmission"], "side").matrix.tolist() == \
        truth.config.transmission.matrix.tolist()
    assert set(side["motor_terms"]) == set(truth.config.transmission.motors)
    capsys.readouterr()
    assert main(["evaluate", str(out), str(config.parent / f"{case}_session2.yaml")]) == 0
    printed = capsys.readouterr().out
    report = json.loads((out / "evaluation_session2.json").read_text())
    assert "mapped to the joints" in printed and report["rows_scored"] > 3000
    assert list(report["joint_rmse_against_logged"]) == truth.config.joints
    per_motor = np.array([report["rmse_against_logged"][m] for m in report["logged_motors"]])
    # the logged current carries white noise of CURRENT_NOISE A: a model at the truth misses a reading by that
    # times the motor's constant (RMS over > 3000 rows: +-1.3 %); 1.25x leaves room for the model's own error
    noise = CURRENT_NOISE * truth.config.transmission.motor_constant
    assert np.all(per_motor < 1.25 * noise), per_motor / noise
