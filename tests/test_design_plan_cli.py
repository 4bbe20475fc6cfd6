"""`robocal plan`: files written, units, determinism, and config errors that name the key."""
import argparse
import json

import numpy as np
import pytest
import yaml

from robocal import load_example
from robocal.errors import InputError
from robocal.cli.plan import add_parser
from robocal.workflows.plan import plan_from_config

CONFIG = {
    "robot": {"example": "ur5"},
    "data": {"csv": "not_measured_yet.csv", "joint_units": {"angle": "deg"}},
    "parameters": {"preset": "full", "frames": {"tool0": True}, "base": True},
    "measurements": [{"type": "pose", "name": "tracker", "frame": "tool0",
                      "columns": ["x", "y", "z", "qx", "qy", "qz", "qw"],
                      "sigma": {"position": 5e-5, "orientation": 5e-5}}],
    "plan": {"N": 20, "seed": 4, "candidates": {"count": 150}, "validation": 40, "curve": [8, 20, 30],
             "volume": {"box": {"min": [-1, -1, -0.2], "max": [1, 1, 1.2]}}},
}


def write_config(tmp_path, **plan):
    cfg = json.loads(json.dumps(CONFIG))
    cfg["plan"].update(plan)
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def run(argv):
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(argv)
    return args.handler(args)


def test_plan_writes_poses_predictions_and_curve(tmp_path, capsys):
    path = write_config(tmp_path)
    assert run(["plan", str(path), "-o", str(tmp_path / "out")]) == 0
    out = tmp_path / "out"
    header, *rows = (out / "poses.csv").read_text().splitlines()
    joints = load_example("ur5").joint_names
    assert header.split(",") == ["pose"] + joints and len(rows) == 20
    q = np.array([[float(v) for v in r.split(",")[1:]] for r in rows])
    assert np.all(np.abs(q) <= 180.0) and np.abs(q).max() > 3.2        # degrees, as the data declares
    doc = yaml.safe_load((out / "poses.yaml").read_text())
    np.testing.assert_allclose([p["values"] for p in doc["poses"]], q, rtol=1e-9)
    pred = json.loads((out / "prediction.json").read_text())
    assert pred["identifiable"] and pred["unidentifiable"] == [] and len(pred["parameters"]) == 30
    assert all(p["stderr"] > 0 and np.isfinite(p["stderr"]) for p in pred["parameters"])
    curve = [c["mean_position_mm"] for c in pred["curve"]]
    assert [c["n_poses"] for c in pred["curve"]] == [8, 20, 30] and curve[0] > curve[1] > curve[2]
    assert pred["tool_accuracy"]["mean_position_mm"] == pytest.approx(curve[1])
    amap = np.loadtxt(out / "accuracy_map.csv", delimiter=",", skiprows=1)
    assert amap.shape == (40, 8)
    np.testing.assert_allclose(np.sqrt(np.sum(amap[:, 4:7] ** 2, axis=1)), amap[:, 3], rtol=1e-4)
    assert "predicted tool0 accuracy" in capsys.readouterr().out


def test_same_seed_same_poses_other_seed_other_poses(tmp_path):
    path = write_config(tmp_path, curve=[20])
    a, b = plan_from_config(path), plan_from_config(path)
    np.testing.assert_array_equal(a.poses, b.poses)
    c = plan_from_config(path, seed=5)
    assert not np.array_equal(a.poses, c.poses)
    # every chosen pose is inside the measurement box
    box = CONFIG["plan"]["volume"]["box"]
    from robocal.model.kinematics import ModelState
    from robocal.model.parameters import ParameterSet
    ms = ModelState(load_example("ur5"), ParameterSet(), a.joint_names)
    p = np.array([ms.sample(v).pose("tool0").translation for v in a.poses])
    assert np.all(p >= box["min"]) and np.all(p <= box["max"])


def test_too_few_poses_exit_code_and_names(tmp_path):
    path = write_config(tmp_path, N=3, curve=[3])
    assert run(["plan", str(path), "-o", str(tmp_path / "few")]) == 3
    pred = json.loads((tmp_path / "few" / "prediction.json").read_text())
    assert not pred["identifiable"] and len(pred["unidentifiable"]) == 12    # 18 rows, 30 parameters
    assert all(any(n in line for line in pred["unidentifiable_explanation"]) for n in pred["unidentifiable"])


@pytest.mark.parametrize("plan, field", [({"criterion": "G"}, "plan.criterion"),
                                         ({"bogus": 1}, "plan.bogus"),
                                         ({"N": 1000}, "plan.N"),
                                         ({"candidates": {"method": "sobol"}}, "plan.candidates.method"),
                                         ({"frame": "tool9"}, "plan.frame")])
def test_config_errors_name_the_key(tmp_path, plan, field):
    path = write_config(tmp_path, **plan)
    with pytest.raises(InputError) as err:
        plan_from_config(path)
    assert err.value.field == field and err.value.source == str(path)
