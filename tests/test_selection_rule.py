"""The committed selection rule (benchmarks/strength_rule.py, docs/validation.md "Choosing a model") on synthetic
truth: a UR5 with an unmodelled joint compliance, measured in one session or in two with the tracker moved between."""
import sys
from pathlib import Path

import numpy as np
import pytest

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.physical_scale import physical_scales
from robocal.workflows.evaluate import setup_for_data
from validation_cases import COMPLIANT, SIGMA, write_sessions

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from strength_rule import STRENGTH_GRID, choose_rung, rung_by_postures, rung_by_sessions  # noqa: E402

LADDER = ({"compliance": False}, None)      # full geometric, full + compliance (the config's own section)
FEW = (0.1, 1.0, None)                      # a short strength grid keeps the tests quick


@pytest.mark.parametrize("c, chosen", [(4e-5, 1), (0.0, 0)])
def test_two_sessions_with_the_tracker_moved_the_rule_picks_compliance_only_when_the_robot_has_it(tmp_path, c,
                                                                                               chosen):
    # 4e-5 rad/(N m) bends the shoulder and elbow by 1-2 mrad under the UR5's 20-60 N m (about 1 mm at the flange,
    # 20 times the noise): leave-one-session-out must find it; with c = 0 the compliance rung can only fit noise
    # and the one-standard-error rule keeps the geometric model
    cfg = write_sessions(tmp_path, c)
    figures = [rung_by_sessions(lambda p=p: [setup_for_data(cfg, f"session{k}.csv", p).problem for k in (1, 2)],
                                strengths=FEW) for p in LADDER]
    assert choose_rung(figures)[0] == chosen
    assert all(f.how == "leave-one-session-out" and len(f.per_strength) == len(FEW) for f in figures)
    if c:
        assert figures[0].rms > 3 * figures[1].rms
    # the chosen rung predicts the other session at the noise level: per point sqrt(3) x 50 um, within twice that
    assert figures[chosen].rms < 2 * np.sqrt(3) * SIGMA * 1e3


@pytest.mark.parametrize("c, chosen", [(4e-5, 1), (0.0, 0)])
def test_one_session_the_closed_form_leave_one_out_picks_compliance_only_when_the_robot_has_it(tmp_path, c, chosen):
    cfg = write_sessions(tmp_path, c)
    figures = [rung_by_postures(lambda p=p: setup_for_data(cfg, parameters=p).problem, strengths=FEW)
               for p in LADDER]
    assert choose_rung(figures)[0] == chosen
    assert all(f.how == "closed-form leave-one-out by posture" for f in figures)
    rms = {s: r for s, r, _ in figures[chosen].per_strength}
    assert figures[chosen].rms == min(rms.values()) and rms[figures[chosen].strength] == figures[chosen].rms


def test_a_given_prior_strength_puts_the_prior_on_every_robot_parameter(tmp_path):
    cfg = write_sessions(tmp_path, 4e-5, n=20)
    setup = setup_for_data(cfg)
    scales = physical_scales(setup.problem)
    result = calibrate(setup.problem, CalibrationOptions(prior_strength=0.1))
    prior = result.default_prior
    assert prior.applied and prior.strength == 0.1 and "given" in prior.describe()
    robot = [n for n in setup.problem.params.select("*") if n in scales.scale]
    assert set(prior.names) == set(robot) and len(robot) > 40
    for n in robot:
        assert setup.problem.params[n].prior_sigma == pytest.approx(0.1 * scales.scale[n])
    assert not any(n.startswith("base.") for n in prior.names)           # the tracker is not the robot
    with pytest.raises(ValueError, match="positive"):
        calibrate(setup_for_data(cfg).problem, CalibrationOptions(prior_strength=-1.0))
    assert STRENGTH_GRID[-1] is None and all(s > 0 for s in STRENGTH_GRID[:-1])
    assert COMPLIANT == ("shoulder_lift_joint", "elbow_joint")
