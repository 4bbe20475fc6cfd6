"""Synthetic truth for the optional model terms (term_selection.py) on simulated UR5 logs read through a
config with candidate terms: a spring on one joint and an effort delay on another; asymmetric Coulomb and
viscous friction on two more. Each true term is kept, comes back within what the noise allows, and no term
is kept on a joint that has none."""
import numpy as np
import pytest

from robocal.workflows.identify import identify_from_config
from ur5_dynamics_cases import COULOMB, VISCOUS, write_ur5_log

SPRING = np.array([0, 0, 0, 0, 3.0, 0])               # N m/rad on wrist_2
DELAY = np.array([0, 0.05, 0, 0, 0, 0])               # s on shoulder_lift
COULOMB_PN = (np.array([COULOMB] * 3 + [1.6] + [COULOMB] * 2), np.array([COULOMB] * 3 + [0.5] + [COULOMB] * 2))
VISCOUS_PN = (np.array([VISCOUS] * 5 + [3.0]), np.array([VISCOUS] * 5 + [1.0]))


@pytest.fixture(scope="module")
def spring_delay(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ur5_spring")
    path, _, _ = write_ur5_log(folder, rows=4000, spring=SPRING, delay=DELAY,
                               candidates=["spring", "coulomb_asymmetric", "viscous_asymmetric", "delay"])
    return identify_from_config(path)


@pytest.fixture(scope="module")
def asymmetric(tmp_path_factory):
    # no offset term nor offset in the truth: an asymmetric Coulomb pair differs from a constant offset only
    # near zero speed (docs/dynamics_tiago.md), so with an offset in the model it is barely identifiable
    folder = tmp_path_factory.mktemp("ur5_asym")
    path, _, _ = write_ur5_log(folder, rows=4000, seed=1, coulomb_pos_neg=COULOMB_PN, viscous_pos_neg=VISCOUS_PN,
                               offset=0.0, terms=("coulomb", "viscous"),
                               candidates=["coulomb_asymmetric", "viscous_asymmetric"])
    return identify_from_config(path)


def kept(res):
    return {(res.recorded.index(t.joint), t.term) for t in res.term_tests if t.kept}


def check_value(res, name, truth):
    """4 standard errors (two-sided 6e-5 each; the standard errors allow for the filtered noise's correlation,
    serial_correlation.py), and a standard error small enough that the test can fail."""
    k = res.ols.names.index(name)
    value, std = res.ols.values[k], res.ols.std[k]
    assert abs(value - truth) < 4 * std, (name, value, truth, std)
    assert std < 0.2 * abs(truth), (name, std)


def test_a_spring_and_a_delay_are_found_and_nothing_else(spring_delay):
    res = spring_delay
    assert kept(res) == {(4, "spring"), (1, "delay")}
    check_value(res, f"{res.recorded[4]}.spring", SPRING[4])
    step = 1.0 / res.processed.fs_raw        # the delay search's grid (the log's median step, ~10 ms)
    assert abs(res.delays[1] - DELAY[1]) <= step + 1e-9 and np.all(res.delays[[0, 2, 3, 4, 5]] == 0)


def test_asymmetric_friction_is_found_where_it_is(asymmetric):
    res = asymmetric
    assert kept(res) == {(3, "coulomb_asymmetric"), (5, "viscous_asymmetric")}
    j = res.recorded
    check_value(res, f"{j[3]}.coulomb_pos", COULOMB_PN[0][3])
    check_value(res, f"{j[3]}.coulomb_neg", COULOMB_PN[1][3])
    check_value(res, f"{j[5]}.viscous_pos", VISCOUS_PN[0][5])
    check_value(res, f"{j[5]}.viscous_neg", VISCOUS_PN[1][5])
