"""Several logs in one identification, and `robocal evaluate IDENTIFY_DIR LOG.yaml` predicting a new log from
the written URDF and side file alone: on a second simulated UR5 session (another trajectory, the same robot)
the prediction at the log's raw rows misses the logged torque by little more than its noise."""
import json

import numpy as np
import yaml

from robocal.cli.main import main
from robocal.workflows.identify import identify_from_config
from ur5_dynamics_cases import EFFORT_NOISE, write_ur5_log


def test_two_logs_train_one_model_and_a_third_is_predicted(tmp_path, capsys):
    first, second, new = (tmp_path / n for n in ("a", "b", "new"))
    for folder in (first, second, new):
        folder.mkdir()
    path, _, _ = write_ur5_log(first, rows=3000, seed=0, robot_seed=2)      # three sessions of one robot
    write_ur5_log(second, rows=3000, seed=3, robot_seed=2)
    write_ur5_log(new, rows=3000, seed=7, robot_seed=2)
    cfg = yaml.safe_load(path.read_text())
    data, windows = cfg.pop("data"), cfg.pop("windows")
    entry = {k: str(first / v) for k, v in data.items() if k != "time_column"}
    cfg["logs"] = [dict(entry, name="a", train=windows["train"], validate=windows["validate"]),
                   {k: v.replace(str(first), str(second)) for k, v in entry.items()} | {"name": "b",
                                                                                       "train": [2.0, 28.0]}]
    (tmp_path / "two.yaml").write_text(yaml.safe_dump(cfg))
    res = identify_from_config(tmp_path / "two.yaml")
    assert [p.part.name for p in res.parts] == ["a", "b"] and res.parts[1].check.sum() == 0
    assert res.n_train == res.parts[0].train.sum() + res.parts[1].train.sum() > 1.8 * res.parts[0].train.sum()
    out = tmp_path / "out"
    assert main(["identify", str(tmp_path / "two.yaml"), "-o", str(out)]) == 0
    full = capsys.readouterr().out
    # -q: what comes before any figure, the status, the held-out figures, the verdict and the URDF; the same files
    assert main(["identify", str(tmp_path / "two.yaml"), "-o", str(tmp_path / "quiet"), "-q"]) == 0
    brief = capsys.readouterr().out
    assert "Signal processing:" in full and "Signal processing:" not in brief and "Wrote" not in brief
    assert len(brief.splitlines()) < len(full.splitlines()) / 2
    for part in ("Dynamic identification:", "Consistent fit: Clarabel status", "Held-out torque RMSE",
                 "Identified URDF:", "summary.txt"):
        assert part in brief, part
    assert (tmp_path / "quiet" / "result.json").read_bytes() == (out / "result.json").read_bytes()
    log_yaml = tmp_path / "new.yaml"
    log_yaml.write_text(yaml.safe_dump({"name": "session3", **{k: str(new / f"{k}.csv") for k in
                                                              ("position", "velocity", "effort")}}))
    capsys.readouterr()
    assert main(["evaluate", str(out), str(log_yaml), "-q"]) == 0
    printed = capsys.readouterr().out
    assert "Wrote" not in printed                             # -q: the figures, not the file list
    report = json.loads((out / "evaluation_session3.json").read_text())
    assert "RMSE vs logged" in printed and report["rows_scored"] > 2000
    logged = np.array(list(report["rmse_against_logged"].values()))
    # the logged torque carries white noise of EFFORT_NOISE: a model close to the truth misses it by about
    # that; 2x leaves room for the filter's smoothing of the kinematics and the fit's own error (the filtered
    # torque is no target here: this trajectory's torque has much content above the identification's cut-off)
    assert np.all(logged < 2 * EFFORT_NOISE), logged
    assert (out / "summary.txt").is_file()                    # the folder's own files are kept
