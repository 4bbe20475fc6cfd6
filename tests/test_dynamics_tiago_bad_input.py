"""Bad input to the identification config: clear errors naming file and field, nothing written."""
import numpy as np
import pytest
import yaml

from robocal.cli.main import main
from robocal.workflows.identify import identify_from_config
from robocal.errors import InputError
from tiago_dynamics_cases import JOINTS, shipped, synthetic_log

ROWS = 1500          # 15 s of the log's time stamps: enough for the windows below, fast


@pytest.fixture
def case(tmp_path):
    cfg, _, _ = synthetic_log(tmp_path / "data", ROWS, train=(1.0, 9.0), validate=(9.0, 14.0), noise=False)
    return cfg, tmp_path


def rewrite(cfg, kind, edit):
    path = cfg["logs"][0][kind]
    data = np.genfromtxt(path, delimiter=",", skip_header=1)
    edit(data)
    header = "t," + ",".join(f"- {j}_{kind}" for j in JOINTS)
    np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.17g")
    return path


def run_and_expect(cfg, tmp_path, match):
    with pytest.raises(InputError, match=match) as info:
        identify_from_config(cfg, tmp_path)
    out = tmp_path / "out"
    (tmp_path / "dyn.yaml").write_text(yaml.safe_dump(cfg))
    assert main(["identify", str(tmp_path / "dyn.yaml"), "-o", str(out)]) == 2
    assert not out.exists() and not list(tmp_path.glob(".out*"))
    return info.value


def test_mismatched_time_stamps_name_the_file_row_and_column(case):
    cfg, tmp_path = case
    path = rewrite(cfg, "velocity", lambda d: d.__setitem__((700, 0), d[700, 0] + 0.002))
    err = run_and_expect(cfg, tmp_path, "time stamp")
    assert err.source == path and err.field == "t" and err.row == 702     # header is line 1


def test_joint_missing_from_the_urdf(case):
    cfg, tmp_path = case
    cfg["robot"]["joints"] = cfg["robot"]["joints"] + ["arm_8_joint"]
    err = run_and_expect(cfg, tmp_path, "arm_8_joint")
    assert err.source.endswith(".urdf") and err.field == "robot.joints"


def test_constant_trajectory_is_refused_naming_the_column(case):
    cfg, tmp_path = case
    path = rewrite(cfg, "position", lambda d: d.__setitem__((slice(None), slice(1, None)), d[0, 1:]))
    err = run_and_expect(cfg, tmp_path, "does not excite")
    assert err.source == path and err.field == "- torso_lift_joint_position"


def test_missing_effort_column_and_overlapping_windows(case):
    cfg, tmp_path = case
    cfg["effort"]["recorded"] = cfg["effort"]["recorded"] + ["arm_5_joint"]
    err = run_and_expect(cfg, tmp_path, "gear_ratio|non-zero")
    assert err.field == "effort.gear_ratio"
    cfg["effort"]["recorded"] = cfg["effort"]["recorded"][:-1]
    cfg["logs"][0]["validate"] = [8.0, 14.0]
    err = run_and_expect(cfg, tmp_path, "overlap")
    assert err.field == "logs[0].validate"


def test_the_shipped_time_stamps_are_irregular():
    """The synthetic cases reuse these stamps: they must carry the log's irregular steps."""
    steps = np.diff(shipped("position")[:, 0])
    assert steps.min() < 0.008 and steps.max() > 0.012


def test_a_training_window_too_short_to_choose_the_prior_weight(case):
    cfg, tmp_path = case
    cfg["signal"]["cutoff_hz"] = 2.0          # a 1 s guard between the fitted and the scored part
    cfg["logs"][0]["train"] = [2.0, 4.5]
    cfg["model"]["prior_rule"] = "holdout"    # the rule that splits the training window
    err = run_and_expect(cfg, tmp_path, "prior weight|widen")
    assert err.field == "windows.train"


def test_positions_in_degrees_are_refused_naming_file_row_and_column(case):
    cfg, tmp_path = case
    path = rewrite(cfg, "position", lambda d: d.__setitem__((slice(None), slice(2, None)), np.degrees(d[:, 2:])))
    err = run_and_expect(cfg, tmp_path, "outside the joint's limits")
    assert err.source == path and err.field == "- arm_1_joint_position" and err.row == 2


def edited_urdf(cfg, tmp_path, link, edit):
    """A copy of the config's URDF with one link's <inertial> edited (edit(element))."""
    from lxml import etree
    root = etree.parse(cfg["robot"]["urdf"]).getroot()
    edit(next(lk for lk in root.findall("link") if lk.get("name") == link).find("inertial"))
    path = tmp_path / "edited.urdf"
    path.write_bytes(etree.tostring(root))
    cfg["robot"]["urdf"] = str(path)
    return path


def test_a_nan_inertia_is_refused_naming_the_link(case):
    cfg, tmp_path = case
    path = edited_urdf(cfg, tmp_path, "arm_2_link", lambda el: el.find("inertia").set("ixx", "nan"))
    err = run_and_expect(cfg, tmp_path, "not finite")
    assert err.source == str(path) and err.field == "link arm_2_link/inertial/inertia@ixx"


def test_a_massless_body_and_an_inconsistent_link_are_noted(case):
    cfg, tmp_path = case
    edited_urdf(cfg, tmp_path, "arm_6_link", lambda el: el.find("mass").set("value", "0"))
    cfg["logs"][0].pop("validate")
    cfg["model"]["candidate_terms"] = []
    res = identify_from_config(cfg, tmp_path)
    assert any("arm_6_joint has CAD mass 0" in n for n in res.notes)
    assert any("arm_1_link' is not a mass distribution" in n for n in res.notes)    # the TIAGo URDF's own
    assert next(b for b in res.bounds if b.joint == "arm_6_joint").mass_range is None


def test_efforts_for_joints_outside_the_model_and_unlogged_efforts(case):
    cfg, tmp_path = case
    rewrite(cfg, "effort", lambda d: d.__setitem__((slice(None), 8), 0.3))     # arm_7's effort column, non-zero
    cfg["robot"]["joints"] = JOINTS[:7]
    cfg["logs"][0].pop("validate")
    cfg["model"]["candidate_terms"] = []
    res = identify_from_config(cfg, tmp_path)
    assert any("'- arm_7_joint_effort' is for a joint not in robot.joints" in n for n in res.notes)
    path = rewrite(cfg, "effort", lambda d: d.__setitem__((slice(None), 3), 0.0))   # arm_2's effort: zeros
    err = run_and_expect(cfg, tmp_path, "zero throughout")
    assert err.source == path and err.field == "- arm_2_joint_effort"


def test_a_validation_window_another_entry_trains_on_is_refused(case):
    cfg, tmp_path = case
    second = dict(cfg["logs"][0], name="again", train=[9.5, 13.0])
    second.pop("validate")
    cfg["logs"].append(second)
    err = run_and_expect(cfg, tmp_path, "validation must be held out")
    assert err.field == "logs[1].train"
