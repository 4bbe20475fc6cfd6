"""Seed 001: the spec's Monte-Carlo table and full-parameter rank (docs/laser_psd.md, "Accuracy").

Noise model: 0.0005 deg per single joint read, 3 reads averaged per pose. Which set-up value reproduces each
figure that does not match the spec within 25 % is computed by benchmarks/laser_psd_setups.py; its search
(robocal.systems.laser_psd.setup_search) is tested here.
"""
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from laser_psd_cases import (DELTA_TRUE, DIRECTION, MOUNT, ROLL, TARGET, exact_readings, joints, readings_for, robot,
                             truth)
from robocal.errors import RobocalError
from robocal.model.dh_urdf import IRB1600_145, dh_urdf
from robocal.model.robot import load_urdf
from robocal.systems.laser_psd.calibration import zero_offset_problem
from robocal.systems.laser_psd.full_parameters import dh_columns, full_parameter_rank
from robocal.systems.laser_psd.monte_carlo import averaged_reading_noise, offset_monte_carlo, predicted_offset_sd
from robocal.systems.laser_psd.plans import multi_fan, patent_fan
from robocal.systems.laser_psd.setup_search import CachedEvaluation, crossings, within

SIGMA_READ = np.radians(0.0005)
N_READS = 3


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


def test_crossings_find_every_root_and_skip_jumps_and_unreachable_values():
    """A figure that crosses its target twice, jumps across it once (no root: a branch flip), and cannot be
    realised at one grid value."""
    def figures(x):
        if x == 2.0:
            raise RobocalError("unreachable")
        y = 1.0 + 0.5 * np.sin(x) if x < 5.0 else 3.0
        return np.array([y, 2 * y])
    ev = CachedEvaluation(figures)
    found = crossings(ev, np.arange(0.0, 7.0, 0.5), 0, 1.25)
    # sin(x) = 0.5 at pi/6 and 5 pi/6; the jump at 5 (1 + 0.5 sin(4.5) < 1.25 < 3) has no root
    assert [round(c.value, 5) for c in found.crossings] == [round(np.pi / 6, 5), round(5 * np.pi / 6, 5)]
    assert found.unreachable == 1 and found.high == 3.0
    assert np.allclose(found.crossings[0].figures, [1.25, 2.5])
    assert within(np.array([1.0, 1.3, 2.0]), np.array([1.0, 1.0, 1.0])) == 1   # 30 % and 100 % off: outside 25 %


def test_turning_the_patent_fan_axis_by_39_deg_reproduces_its_joint_4_figure():
    """docs/laser_psd.md, "Which set-up reproduces each figure" (benchmarks/laser_psd_setups.py): the fan axis
    turned about base z between 35 and 45 deg takes joint 4's predicted sd through the spec's 0.0033 deg."""
    def predicted(angle_deg):
        axis = (np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg)), 0.0)
        return np.degrees(predicted_offset_sd(robot(), joints(), truth(), MOUNT, patent_fan(axis=axis), TARGET,
                                              DIRECTION, ROLL, SIGMA_READ / np.sqrt(N_READS)))
    found = crossings(CachedEvaluation(predicted), [35.0, 45.0], 2, 0.0033, xtol=1e-3)
    assert len(found.crossings) == 1 and 35 < found.crossings[0].value < 45
    # within the 1 % crossings() demands; the stated set-up (axis base x) is 0.58x
    assert abs(found.crossings[0].figures[2] / 0.0033 - 1) < 0.01


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
