"""`robocal iso9283 CONFIG` on a synthetic UR5 dataset: calibration rows plus ISO rows (3 poses x 6 cycles)."""
import argparse
import json

import numpy as np
import pinocchio as pin
import pytest
import yaml

from robocal import load_example
from robocal.io.tables import write_csv
from robocal.errors import InputError
from robocal.estimation.iso9283 import iso9283_figures, pose6
from robocal.cli.iso9283 import add_parser, cmd_iso9283
from robocal.workflows.iso9283 import iso9283_from_config
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters
from robocal.design.simulate import perturb, random_configurations

SIGMA_M, SIGMA_Q = 2e-5, 5e-5     # tracker noise (m, rad); joint repeatability (rad)
N_CAL, N_POSES, CYCLES = 50, 3, 6
JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint"]


def _write_dataset(folder, seed=31):
    rng = np.random.default_rng(seed)
    robot = load_example("ur5")
    params = robot_parameters(robot, JOINTS, "full", frames={"tool0": True}, base=True)
    truth = perturb(params, rng, 2e-3, np.radians(0.2))
    nominal, true = ModelState(robot, params, JOINTS), ModelState(robot, truth, JOINTS)
    q_cal = random_configurations(robot, JOINTS, N_CAL, rng)
    q_iso = random_configurations(robot, JOINTS, N_POSES, rng, span=0.7)
    rows_q, ids, cmd = list(q_cal), [""] * N_CAL, [None] * N_CAL
    for _ in range(CYCLES):
        for k in range(N_POSES):
            rows_q.append(q_iso[k] + rng.normal(0, SIGMA_Q, 6))
            ids.append(f"P{k + 1}")
            cmd.append(nominal.sample(q_iso[k]).pose("tool0"))
    meas = []
    for q in rows_q:
        M = true.sample(q).pose("tool0")
        meas.append(pin.SE3(pin.exp3(rng.normal(0, SIGMA_M, 3)) @ M.rotation, M.translation + rng.normal(0, SIGMA_M, 3)))
    q = np.array(rows_q)
    cols = {j: q[:, i] for i, j in enumerate(JOINTS)}
    for name, poses in (("", meas), ("c", [c if c is not None else pin.SE3.Identity() for c in cmd])):
        arr = np.array([np.r_[M.translation * 1e3, pin.Quaternion(M.rotation).coeffs()] for M in poses])
        for i, c in enumerate(("x", "y", "z", "qx", "qy", "qz", "qw")):
            cols[c + name] = arr[:, i]
    write_csv(folder / "iso.csv", cols)
    # write_csv writes numbers only: add the pose-id column as text
    lines = (folder / "iso.csv").read_text().splitlines()
    text = "\n".join([lines[0] + ",pose"] + [l + "," + i for l, i in zip(lines[1:], ids)]) + "\n"
    (folder / "iso.csv").write_text(text)
    config = {"robot": {"example": "ur5"}, "data": {"csv": "iso.csv", "units": {"length": "mm"}},
              "parameters": {"preset": "full", "frames": {"tool0": True}, "base": True},
              "measurements": [{"type": "pose", "name": "tracker", "frame": "tool0",
                                "columns": ["x", "y", "z", "qx", "qy", "qz", "qw"],
                                "sigma": {"position": SIGMA_M, "orientation": SIGMA_M}}],
              "iso9283": {"pose_id": "pose", "measurement": "tracker",
                          "commanded": ["xc", "yc", "zc", "qxc", "qyc", "qzc", "qwc"]}}
    (folder / "iso.yaml").write_text(yaml.safe_dump(config))
    return folder / "iso.yaml", dict(ids=ids[N_CAL:], cmd=cmd[N_CAL:], meas=meas[N_CAL:], true=true, q_iso=q_iso)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return _write_dataset(tmp_path_factory.mktemp("iso"))


@pytest.fixture(scope="module")
def run(dataset):
    return iso9283_from_config(dataset[0])


def test_nominal_figures_are_those_of_the_measured_poses(dataset, run):
    _, d = dataset
    # the CSV holds mm with 17 digits: the round trip costs < 1e-15 m
    direct = iso9283_figures(d["ids"], [pose6(P) for P in d["cmd"]], [pose6(M) for M in d["meas"]])
    assert [p.pose_id for p in run.nominal.poses] == ["P1", "P2", "P3"]
    for a, b in zip(run.nominal.poses, direct.poses):
        assert abs(a.AP - b.AP) < 1e-9 and abs(a.RP - b.RP) < 1e-9
        assert np.abs(a.AP_abc - b.AP_abc).max() < 1e-9 and np.abs(a.RP_abc - b.RP_abc).max() < 1e-9
    for a, b in zip(run.nominal.distances, direct.distances):
        assert abs(a.AD - b.AD) < 1e-9 and abs(a.RD - b.RD) < 1e-9


def test_calibration_removes_the_bias_and_keeps_the_repeatability(run):
    assert run.result is not None and run.result.success
    for fn, fc in zip(run.nominal.poses, run.calibrated.poses):
        # one rigid transform per pose: distances to the barycentre are unchanged
        assert abs(fn.RP - fc.RP) < 1e-12
        # Left after calibration: the barycentre's noise, per axis at most
        # s = sqrt(SIGMA_Q^2 * 6 * (1 m lever)^2 + SIGMA_M^2) = 1.2e-4 m spread / sqrt(6) visits, plus the
        # calibrated model's own error (~10 um from 90 poses at 20 um). Bound: sqrt(3) * 5 * s / sqrt(6) + 50 um.
        s = np.sqrt(SIGMA_Q ** 2 * 6 + SIGMA_M ** 2)
        assert fc.AP < np.sqrt(3) * 5 * s / np.sqrt(CYCLES) + 5e-5
        assert fn.AP > 3 * fc.AP   # 2 mm / 0.2 deg of true errors: the nominal bias is mm-sized
    assert len(run.calibrated.distances) == 2


def test_cli_prints_and_writes_json(dataset, tmp_path, capsys):
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command"))
    out = tmp_path / "iso.json"
    args = parser.parse_args(["iso9283", str(dataset[0]), "-o", str(out)])
    assert cmd_iso9283(args) == 0
    text = capsys.readouterr().out
    assert "positions in mm, angles in mrad" in text and "nominal" in text and "calibrated" in text
    doc = json.loads(out.read_text())
    assert doc["units"] == "SI (m, rad)" and [p["pose"] for p in doc["calibrated"]["poses"]] == ["P1", "P2", "P3"]
    with pytest.raises(InputError, match="file exists"):
        cmd_iso9283(args)


def test_parameters_from_a_result_file_give_the_same_figures(dataset, run, tmp_path):
    doc = {"parameters": [p.to_dict() for p in run.result.params]}
    (tmp_path / "result.json").write_text(json.dumps(doc))
    again = iso9283_from_config(dataset[0], tmp_path / "result.json")
    assert again.result is None
    for a, b in zip(again.calibrated.poses, run.calibrated.poses):
        assert abs(a.AP - b.AP) < 1e-12


def test_config_mistakes_are_named(dataset, tmp_path):
    raw = yaml.safe_load(dataset[0].read_text())
    (tmp_path / "iso.csv").write_text((dataset[0].parent / "iso.csv").read_text())
    (tmp_path / "none.json").write_text('{"parameters": []}')   # nominal values: no fit needed
    cases = [({"pose_id": "station"}, r"iso.csv, field 'station': missing column"),
             ({"pose_id": "pose", "measurment": "x"}, r"field 'iso9283.measurment': unknown key \(did you mean"),
             ({"pose_id": "pose", "measurement": "mocap"}, r"no pose block named 'mocap'"),
             ({"pose_id": "pose", "commanded": ["xc"]}, r"commanded needs 7 columns"),
             ({"pose_id": "pose", "distance_pairs": [["P1", "P9"]]}, r"names pose 'P9', which the data do not have")]
    for section, message in cases:
        raw["iso9283"] = section
        (tmp_path / "bad.yaml").write_text(yaml.safe_dump(raw))
        with pytest.raises(InputError, match=message):
            iso9283_from_config(tmp_path / "bad.yaml", parameters=tmp_path / "none.json")
    raw.pop("iso9283")
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(raw))
    with pytest.raises(InputError, match="needs an 'iso9283' section"):
        iso9283_from_config(tmp_path / "bad.yaml")
