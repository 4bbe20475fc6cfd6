"""The five-mode study behind examples/stewart_calibration.py: its data sets are consistent (noise-free,
every mode alone and the mix recover the machine) and its noise enters at the stated level."""
from pathlib import Path

import numpy as np
import pytest

import robocal
from robocal.systems.stewart import modes as sm
from robocal.systems.stewart.mode_study import BALLS, BAR_BASES, HOLES, PLANES, ModeStudy, mix

URDF = Path(__file__).resolve().parents[1] / "urdf" / "stewart_6_6.urdf"
TOOL = sm.Tool(0.2, 0.003)


@pytest.fixture(scope="module")
def robot():
    return robocal.load_urdf(URDF)


@pytest.mark.parametrize("mode", ["planes", "holes", "balls", "ball_bar"])
def test_each_contact_mode_alone_recovers_the_machine_without_noise(robot, mode):
    study = ModeStudy(robot, TOOL, seed=1, noise=0.0)
    result, tip = study.fit(getattr(study, mode)(12), fix_platform_joints=True)
    assert result.success
    # noise-free: what is left is the loop assembly's round-off (1e-12 m) through the fit and the FK
    assert tip < 1e-9


def test_mix_of_all_modes_recovers_all_42_parameters_without_noise(robot):
    study = ModeStudy(robot, TOOL, seed=2, noise=0.0)
    parts = [study.full_poses(6)]
    for make, objects in ((study.planes, PLANES[:1]), (study.holes, HOLES[:1]), (study.balls, BALLS[:1]),
                          (study.ball_bar, BAR_BASES[:1])):
        parts.append(make(10, first=sum(len(p.struts) for p in parts), objects=objects))
    data = mix(parts)
    assert len(data.struts) == 6 + 4 * 10
    result, tip = study.fit(data, fix_platform_joints=False)
    assert result.success and result.selection.rank == 43        # 42 + the ball bar's origin offset
    assert tip < 1e-9


def test_noise_enters_the_ball_bar_readings_at_the_stated_level(robot):
    quiet = ModeStudy(robot, TOOL, seed=3, noise=0.0).ball_bar(200)
    noisy = ModeStudy(robot, TOOL, seed=3, sig_p=1e-6).ball_bar(200)
    # same machine and poses (same seed, noise drawn after the poses): the readings differ by the noise
    # alone; its sd from 600 draws has a spread of 1/sqrt(1200) = 3 %, allow 15 %
    d = np.concatenate([n.measurements[:, 0] - q.measurements[:, 0] for n, q in zip(noisy.residuals, quiet.residuals)])
    assert abs(d.std() / 1e-6 - 1) < 0.15
