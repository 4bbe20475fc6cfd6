"""Seed 001: the spec's Monte-Carlo table and full-parameter rank (docs/laser_psd.md, "Accuracy").

Noise model: 0.0005 deg per single joint read, 3 reads averaged per pose. Figures that do not match the
spec within 25 % are each given a reason here that a run can check (see the docs page's table).
"""
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from laser_psd_cases import DELTA_TRUE, DIRECTION, MOUNT, TARGET, exact_readings, joints, readings_for, robot, truth
from robocal.model.dh_urdf import IRB1600_145, dh_urdf
from robocal.model.robot import load_urdf
from robocal.systems.laser_psd.calibration import zero_offset_problem
from robocal.systems.laser_psd.full_parameters import dh_columns, full_parameter_rank
from robocal.systems.laser_psd.monte_carlo import averaged_reading_noise, offset_monte_carlo, sweep_predicted_sd
from robocal.systems.laser_psd.plans import multi_fan, patent_fan

SIGMA_READ = np.radians(0.0005)
N_READS = 3
SPEC = {"patent": np.radians([0.145, 0.029, 0.0033, 0.0007, 0.031]),
        "three_fans": np.radians([0.011, 0.0026, 0.0006, 0.0003, 0.0057])}


def test_full_parameter_mode_has_rank_19_of_32():
    # 24 DH parameters + the beam (origin 3, direction 2) + the PSD point, 56 poses at the spec's constant
    # 350 mm stand-off. Null: scale, joint 1's turn and lift (base gauge), d2 - d3 (parallel axes), the
    # beam's origin along itself, joint 6's four DH parameters against the beam, and its direction (one
    # stand-off fixes only one point of it); the gap is 1e-3 -> 1e-13, so the count is not a tolerance.
    plan = multi_fan(n_per_fan=19)[:56]
    r = full_parameter_rank(robot(), joints(), readings_for(MOUNT, plan), MOUNT, offsets=DELTA_TRUE, target=TARGET)
    assert len(r.names) == 32 and r.rank == 19
    assert r.singular_values[18] > 1e-4 * r.singular_values[0] > 1e4 * r.singular_values[19]
    # a varied stand-off shows the beam direction and the tool-side DH parameters it was confounded with
    plan = multi_fan(n_per_fan=19, standoffs=np.linspace(0.30, 0.40, 19))[:56]
    assert full_parameter_rank(robot(), joints(), readings_for(MOUNT, plan), MOUNT, offsets=DELTA_TRUE,
                               target=TARGET).rank == 23


def test_averaged_reads_carry_the_read_noise_over_sqrt_n():
    noise = averaged_reading_noise(np.random.default_rng(0), (4000, 6), 1.0, 3)
    # sd of a sample sd from 24000 draws: 1/sqrt(48000) = 0.46 %; allow 2 % (4 spreads)
    assert abs(noise.std() * np.sqrt(3) - 1) < 0.02


def test_monte_carlo_rms_matches_the_prediction_under_read_averaging():
    mc = offset_monte_carlo(robot(), joints(), exact_readings("three_fans"), MOUNT, DELTA_TRUE, SIGMA_READ,
                            N_READS, trials=40, seed=3)
    # the prediction uses sigma_read / sqrt(3); sum over trials of e^T C^-1 e ~ chi2(5 * 40) if the
    # Monte Carlo and the prediction describe the same noise (two-sided 99.9 % band); a wrong sqrt(3)
    # would put it at 3x or 1/3 of its mean, far outside
    cov = np.outer(mc.predicted_sd, mc.predicted_sd)      # diagonal check per offset, then jointly
    chi2 = np.sum(mc.errors ** 2 / np.diag(cov))
    assert stats.chi2.ppf(0.0005, 5 * 40) < chi2 < stats.chi2.ppf(0.9995, 5 * 40)


def test_spec_figures_outside_25_percent_have_a_checked_reason():
    """The spec does not say how the beam frame is spun about the beam (roll) nor the fan axes' frame.
    Swept over both, robocal's predicted sd spans a range per offset. Three of the spec's figures lie
    outside their range by more than 25 %: no set-up of this family with this noise model gives them
    (patent joint 6, three-fan joints 4 and 5). The others lie inside it: they depend on the open choice
    (docs/laser_psd.md lists them)."""
    rolls = np.radians(np.arange(-180.0, 180.0, 60.0))
    makers = {"patent_x": lambda R: patent_fan(axis=(1, 0, 0)), "patent_y": lambda R: patent_fan(axis=(0, 1, 0)),
              "patent_beam_x": lambda R: patent_fan(axis=R[:, 0]), "three_fans": lambda R: multi_fan()}
    sd = sweep_predicted_sd(robot(), joints(), truth(), MOUNT, TARGET, DIRECTION, rolls, makers,
                            SIGMA_READ / np.sqrt(N_READS))
    patent = np.array([v for (k, _), v in sd.items() if k.startswith("patent") and np.all(v < 0.02)])
    three = np.array([v for (k, _), v in sd.items() if k == "three_fans"])
    assert len(patent) >= 12 and len(three) >= 5
    assert patent[:, 4].min() > 1.25 * SPEC["patent"][4]          # joint 6: robocal at least 2x worse
    assert three[:, 2].max() < SPEC["three_fans"][2] / 1.25       # joint 4: robocal about 2x better
    assert three[:, 3].min() > 1.25 * SPEC["three_fans"][3]       # joint 5: robocal 1.4-2.7x worse
    # the rest of the spec's figures are reached by some set-up of the family
    for k in (0, 1, 2, 3):
        assert patent[:, k].min() / 1.25 <= SPEC["patent"][k] <= 1.25 * patent[:, k].max()
    for k in (0, 1, 4):
        assert three[:, k].min() / 1.25 <= SPEC["three_fans"][k] <= 1.25 * three[:, k].max()


@pytest.mark.parametrize("name", ["joint_1.alpha", "joint_2.a", "joint_3.alpha", "joint_4.d", "joint_5.theta",
                                  "joint_6.a", "joint_6.alpha"])
def test_dh_columns_match_finite_differences_of_the_dh_table(tmp_path, name):
    """Each DH column (a fixed combination of placement twists) against the residual of a robot rebuilt
    from the DH table with that entry moved by +-h. At the truth (zero residual), so the row basis's
    own dependence on the model does not enter to first order."""
    q = exact_readings("patent")
    problem = zero_offset_problem(robot(), joints(), q, MOUNT, mount_free=True, preset="full",
                                  frames={"tool0": True}, target_guess=TARGET)
    for j, d in zip(joints(), DELTA_TRUE):
        problem.params[f"{j}.offset"].value = d
    names, T = dh_columns(problem, joints(), "tool0")
    column = (problem.evaluate().J @ T)[:, names.index(name)]
    joint, field = name.split(".")
    k = joints().index(joint)
    attr = {"a": "a", "alpha": "alpha", "d": "d", "theta": "theta_offset"}[field]
    h = 1e-6

    def residual(step):
        rows = list(IRB1600_145)
        rows[k] = replace(rows[k], **{attr: getattr(rows[k], attr) + step})
        path = tmp_path / f"dh_{step:+g}.urdf"
        path.write_text(dh_urdf(rows, "moved", end_link="tool0"))
        moved = zero_offset_problem(load_urdf(path), joints(), q, MOUNT, mount_free=True, target_guess=TARGET)
        for j, d in zip(joints(), DELTA_TRUE):
            moved.params[f"{j}.offset"].value = d
        return moved.evaluate(jacobian=False).r

    fd = (residual(h) - residual(-h)) / (2 * h)
    # central differences: truncation h^2 |r'''| ~ 1e-12 |r'|; rounding eps |r| / h with r ~ 1e-6 at
    # +-h: ~1e-10; the URDF's printed digits (format_numbers, 1e-12 and finer) stay below both
    assert np.abs(fd - column).max() < 1e-6 * max(np.abs(column).max(), 1.0)
