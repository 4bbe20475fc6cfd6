"""Issue 18 with synthetic truth: safe defaults on weak data, model selection, evaluate, grouped CV, bad input.

The data are a simulated UR5 seen at its flange by a tracker with 50 um noise per axis (validation_cases)."""
import json

import numpy as np
import pytest

from robocal.cli.main import main
from robocal.errors import InputError
from robocal.estimation.calibrate import calibrate
from robocal.workflows.evaluate import setup_for_data
from robocal.workflows.select import select_model
from robocal.estimation.physical_scale import BEYOND, physical_scales
from robocal.estimation.cross_validation import cv_table
from robocal.workflows.cv import group_folds
from robocal.model.kinematics import ModelState
from validation_cases import JOINTS, SIGMA, write_case

WEAK = {"wrist_2_joint": 0.02, "wrist_3_joint": 0.02}    # two wrist joints barely move: weak directions


def test_weak_and_confounded_data_converge_physically_with_the_default_prior(tmp_path):
    cfg, _, _ = write_case(tmp_path, np.random.default_rng(1), n=30, spread=WEAK)
    setup = setup_for_data(cfg)
    result = calibrate(setup.problem, setup.options)
    assert result.success and result.default_prior.applied
    scales = physical_scales(setup.problem)
    for name, s in scales.scale.items():               # every robot parameter within physical scale
        assert abs(setup.problem.params[name].value) < BEYOND * s, name
    # structurally confounded pairs: decided by the prior alone, and said so
    assert result.prior_only and all(result.determinacy.classes[n] == "set by the prior" for n in result.prior_only)
    decided = [d for d in result.determinacy.directions if d.decided_by_prior]
    assert decided and any("wrist" in n for d in decided for n, _ in d.terms)
    assert any("its prior decides it" in s for s in result.identifiability_statements())
    # the same data without the prior: refused, with the way forward printed first
    off = setup_for_data(cfg)
    off.options.regularisation = "none"
    refused = calibrate(off.problem, off.options)
    assert not refused.success and refused.refusals
    text = refused.summary()
    assert text.startswith("Refused (1)") and "Fix:" in text and "regularisation: auto" in text


def _compliance_case(tmp_path, rng, c):
    # 4e-5 rad/(N m) under the UR5's 20-60 N m shoulder and elbow loads bends them by 1-2 mrad: about 1 mm at
    # the flange, 20 times the noise; the ladder's compliance rung can see it, the geometric ones cannot.
    comp = {"shoulder_lift_joint": c, "elbow_joint": c}
    return write_case(tmp_path, rng, n=36, compliance=comp, parameters={"compliance": list(comp)})


@pytest.mark.parametrize("c, expected", [(4e-5, "full + compliance"), (0.0, "full geometric")])
def test_select_picks_compliance_only_when_the_data_hold_it(tmp_path, c, expected):
    cfg, _, _ = _compliance_case(tmp_path, np.random.default_rng(2), c)
    selection = select_model(cfg, folds=4)
    assert selection.rungs[selection.chosen].name == expected
    assert [r.name for r in selection.rungs] == ["registration", "joint offsets", "full geometric",
                                                 "full + compliance"]
    assert any(line.startswith("*") for line in selection.table())


def test_evaluate_hand_computed_errors_inside_and_outside_the_training_range(tmp_path):
    cfg, truth, values = write_case(tmp_path, np.random.default_rng(3), n=30, geometric=False)
    out = tmp_path / "out"
    assert main(["calibrate", str(cfg), "-o", str(out), "-q", "--no-report"]) == 0
    fitted = setup_for_data(cfg)
    for p in json.loads((out / "result.json").read_text())["parameters"]:
        fitted.problem.params[p["name"]].value = p["value"]
    ms = ModelState(fitted.problem.robot, fitted.problem.params, JOINTS)
    q = np.array([values[0], values[1], values[2]])
    q[2, 0] = values[:, 0].max() + 0.5                   # shoulder pan 0.5 rad beyond the training range
    shift = np.array([[3e-3, 0, 0], [0, 4e-3, 0], [0, 0, 2e-3]])   # errors the model cannot know
    pts = np.array([ms.sample(v).pose("tool0").translation for v in q]) - shift
    rows = [",".join(JOINTS + ["x", "y", "z"])] + [",".join(repr(float(x)) for x in [*v, *p]) for v, p in zip(q, pts)]
    (tmp_path / "other.csv").write_text("\n".join(rows) + "\n")
    assert main(["evaluate", str(out), str(tmp_path / "other.csv"), "--config", str(cfg)]) == 0
    ev = json.loads((out / "evaluation_other.json").read_text())
    b = ev["blocks"][0]
    # hand-computed: inside |e| = 3 and 4 mm -> RMS sqrt((9 + 16) / 2); outside 2 mm; all three sqrt(29 / 3)
    assert b["inside_training_range"]["rms_norm"] == pytest.approx(np.sqrt(12.5), abs=1e-6)
    assert b["outside_training_range"]["rms_norm"] == pytest.approx(2.0, abs=1e-6)
    assert b["all"]["rms_norm"] == pytest.approx(np.sqrt(29 / 3), abs=1e-6) and b["all"]["max_norm"] == pytest.approx(4)
    assert [o["csv_line"] for o in ev["outside_training_range"]] == [4]
    assert ev["refitted"] == []


def test_grouped_cv_never_splits_a_group(tmp_path):
    groups = [f"s{k % 5}" for k in range(30)]
    cfg, _, _ = write_case(tmp_path, np.random.default_rng(4), n=30, groups=groups, geometric=False,
                           parameters={"preset": "offsets"})
    setup = setup_for_data(cfg)
    folds = group_folds(setup, "session")
    assert len(folds) == 5
    for fold in folds:
        labels = {groups[i] for i in fold}
        assert len(labels) == 1
        assert all(groups[i] not in labels for i in np.setdiff1d(np.arange(30), fold))
    table = cv_table(setup.problem, folds, setup.options)
    assert [sorted(f["held_out_samples"]) for f in table.folds] == [sorted(f.tolist()) for f in folds]
    # offsets model on offsets-free data: held-out error near the 3D noise norm sqrt(3) * 50 um
    assert 0.5 * np.sqrt(3) * SIGMA * 1e3 < table.rms < 2 * np.sqrt(3) * SIGMA * 1e3


def test_bad_input_names_file_and_field_and_writes_nothing(tmp_path, capsys):
    cfg, _, values = write_case(tmp_path, np.random.default_rng(5), n=20, geometric=False,
                                parameters={"preset": "offsets"})
    with pytest.raises(InputError) as exc:
        group_folds(setup_for_data(cfg), "operator")
    assert "data.csv" in str(exc.value) and "operator" in str(exc.value)
    assert main(["cv", str(cfg), "--group", "operator"]) == 2
    out = tmp_path / "out"
    assert main(["calibrate", str(cfg), "-o", str(out), "-q", "--no-report"]) == 0
    before = sorted(p.name for p in out.iterdir())
    # an evaluation CSV without a joint column
    (tmp_path / "bad.csv").write_text("shoulder_pan_joint,x,y,z\n0,0,0,0\n")
    assert main(["evaluate", str(out), str(tmp_path / "bad.csv"), "--config", str(cfg)]) == 2
    assert "bad.csv" in capsys.readouterr().err
    # a result folder of another model: its parameters are not in this config's model
    result = json.loads((out / "result.json").read_text())
    result["parameters"].append({"name": "arm_7_joint.offset", "value": 0.0})
    (out / "result.json").write_text(json.dumps(result))
    assert main(["evaluate", str(out), str(tmp_path / "data.csv"), "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert "result.json" in err and "arm_7_joint.offset" in err
    assert sorted(p.name for p in out.iterdir()) == before


def test_evaluate_refuses_a_session_in_other_units_and_writes_nothing(tmp_path, capsys):
    """The other session's positions 1000x too small for the config's unit (metres read as mm, say): the
    cell-magnitude check cannot see it, the spread check calibrate runs does."""
    cfg, _, _ = write_case(tmp_path, np.random.default_rng(6), n=20, geometric=False,
                           parameters={"preset": "offsets"})
    out = tmp_path / "out"
    assert main(["calibrate", str(cfg), "-o", str(out), "-q", "--no-report"]) == 0
    before = sorted(p.name for p in out.iterdir())
    lines = (tmp_path / "data.csv").read_text().splitlines()
    header = lines[0].split(",")
    xyz = [header.index(c) for c in ("x", "y", "z")]
    rows = [[float(v) * (1e-3 if k in xyz else 1.0) for k, v in enumerate(line.split(","))] for line in lines[1:]]
    (tmp_path / "small.csv").write_text("\n".join([lines[0]] + [",".join(repr(v) for v in r) for r in rows]) + "\n")
    assert main(["evaluate", str(out), str(tmp_path / "small.csv"), "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert "small.csv" in err and "data.units" in err
    assert sorted(p.name for p in out.iterdir()) == before
