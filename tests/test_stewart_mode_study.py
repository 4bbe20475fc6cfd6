"""The five-mode study behind examples/stewart_calibration.py: its data sets are consistent (noise-free,
every mode alone and the mix recover the machine), each instrument's error enters at its stated level, the
ball bar is one instrument, and the CMM's error on the platform joints is carried into the fit."""
from pathlib import Path

import numpy as np
import pytest

import robocal
from robocal.estimation.calibrate import calibrate
from robocal.estimation.problem import Problem
from robocal.systems.stewart import calibration as sc
from robocal.systems.stewart import modes as sm
from robocal.systems.stewart.mode_study import (BALLS, BAR, BAR_BASES, BAR_ORIGIN_OFFSET, BAR_TRAVEL, HOLES, PLANES,
                                                ModeStudy, mix, platform_names)

URDF = Path(__file__).resolve().parents[1] / "urdf" / "stewart_6_6.urdf"
TOOL = sm.Tool(0.2, 0.003)


@pytest.fixture(scope="module")
def robot():
    return robocal.load_urdf(URDF)


@pytest.mark.parametrize("mode", ["planes", "holes", "balls", "ball_bar"])
def test_each_contact_mode_alone_recovers_the_machine_without_noise(robot, mode):
    study = ModeStudy(robot, TOOL, seed=1, noise=0.0)
    result, tip = study.fit(getattr(study, mode)(48), platform_joints="cmm_prior")
    assert result.success
    # noise-free (the CMM too): what is left is the loop assembly's round-off (1e-12 m) through the fit and the FK
    assert tip < 1e-9


def test_mix_of_all_modes_recovers_all_42_parameters_without_noise(robot):
    study = ModeStudy(robot, TOOL, seed=2, noise=0.0)
    parts = [study.full_poses(6)]
    for make, objects in ((study.planes, PLANES[:1]), (study.holes, HOLES[:1]), (study.balls, BALLS[:1]),
                          (study.ball_bar, BAR_BASES[:1])):
        parts.append(make(10, first=sum(len(p.struts) for p in parts), objects=objects))
    data = mix(parts)
    assert len(data.struts) == 6 + 4 * 10
    result, tip = study.fit(data, platform_joints="free")
    assert result.success and result.selection.rank == 43        # 42 + the ball bar's origin offset
    assert tip < 1e-9


def test_the_ball_bar_is_one_instrument_with_one_origin_offset(robot):
    study = ModeStudy(robot, TOOL, seed=4, noise=0.0)
    data = study.ball_bar(60)
    assert [len(r.samples) for r in data.residuals] == [20, 20, 20]       # 60 contacts over its 3 places
    # readings within the bar's travel about its zero
    assert np.abs(np.concatenate([r.measurements[:, 0] for r in data.residuals])).max() <= BAR_TRAVEL
    params = study.parameters("cmm_prior")
    problem = Problem(robot, params, sc.actuated(robot), data.struts, data.residuals)
    assert [p.name for p in problem.params if p.kind == "auxiliary" and p.vary] == [f"{BAR}.offset"]
    calibrate(problem)
    # noise-free: the one offset is found to the loop assembly's round-off
    assert abs(params[f"{BAR}.offset"].value - BAR_ORIGIN_OFFSET) < 1e-10


def test_noise_enters_the_ball_bar_readings_and_the_struts_at_the_stated_level(robot):
    quiet = ModeStudy(robot, TOOL, seed=3, noise=0.0).ball_bar(600)
    noisy = ModeStudy(robot, TOOL, seed=3, sig_p=1e-6, sig_s=2e-6).ball_bar(600)
    # same machine and poses (same seed, noise drawn after the poses): the readings differ by the noise
    # alone; a sd from 600 draws has a spread of 1/sqrt(1200) = 3 %, allow 15 %
    d = np.concatenate([n.measurements[:, 0] - q.measurements[:, 0] for n, q in zip(noisy.residuals, quiet.residuals)])
    assert abs(d.std() / 1e-6 - 1) < 0.15
    # struts: 3600 readings, spread 1.2 %, allow 5 %
    assert abs((noisy.struts - quiet.struts).std() / 2e-6 - 1) < 0.05


def test_the_cmm_measures_the_platform_joints_with_its_stated_error(robot):
    d = np.concatenate([[s.cmm[n] - s.truth[n].value for n in platform_names()]
                        for s in (ModeStudy(robot, TOOL, seed=k, sig_cmm=5e-6) for k in range(20))])
    # 360 draws: the sd's spread is 1/sqrt(720) = 3.7 %, allow 15 %; the mean within 4 sd / sqrt(360)
    assert len(d) == 360 and abs(d.std() / 5e-6 - 1) < 0.15 and abs(d.mean()) < 4 * 5e-6 / np.sqrt(360)


def test_the_cmm_error_is_carried_into_the_fit_not_frozen(robot):
    """Contacts nearly exact (1 nm), the CMM 5 um off: T fixed at the CMM's values leaves its error in the
    machine (um at the tip); T as priors of 5 um lets the contacts correct what they see, and what they do
    not see (T turning about the tip) does not move the tip."""
    tips = {}
    for pj in ("cmm_fixed", "cmm_prior"):
        study = ModeStudy(robot, TOOL, seed=5, sig_p=1e-9, sig_s=1e-9, sig_cmm=5e-6)
        result, tips[pj] = study.fit(study.balls(120), platform_joints=pj)
        assert result.success
    # fixed: a 5 um error per coordinate of T reaches the tip at the um level (~ its size); with priors the
    # floor is the 1 nm contact noise amplified by the design (~1e2): below 0.1 um
    assert tips["cmm_fixed"] > 1e-6 and tips["cmm_prior"] < 1e-7
