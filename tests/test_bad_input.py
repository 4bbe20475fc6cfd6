"""Bad input: a clear error naming file, row and field; non-zero exit; no output written."""
import csv
import shutil
from pathlib import Path

import pytest

from robocal.cli.main import main

DEMO = Path(__file__).parents[1] / "robocal" / "io" / "demo"


def _setup(tmp_path, edit_rows=None, config_edit=None, n_rows=None):
    rows = list(csv.reader(open(DEMO / "ur5_tracker_poses.csv")))
    header, data = rows[0], rows[1:]
    if n_rows is not None:
        data = data[:n_rows]
    if edit_rows:
        header, data = edit_rows(header, data)
    with open(tmp_path / "ur5_tracker_poses.csv", "w", newline="") as f:
        csv.writer(f).writerows([header] + data)
    cfg = (DEMO / "ur5_calibrate.yaml").read_text()
    if config_edit:
        cfg = config_edit(cfg)
    (tmp_path / "calib.yaml").write_text(cfg)
    return tmp_path / "calib.yaml"


def _run(cfg, capsys):
    code = main(["calibrate", str(cfg), "-q"])
    err = capsys.readouterr().err
    assert not (cfg.parent / "robocal-output").exists(), "no output may be written on bad input"
    assert not list(cfg.parent.glob(".robocal-output*")), "no temporary output may be left behind"
    return code, err


def test_missing_joint_column(tmp_path, capsys):
    def drop(header, data):
        k = header.index("elbow_joint")
        return header[:k] + header[k + 1:], [r[:k] + r[k + 1:] for r in data]
    code, err = _run(_setup(tmp_path, drop), capsys)
    assert code == 2
    assert "ur5_tracker_poses.csv" in err and "'elbow_joint'" in err and "missing column" in err


def test_nan_in_a_row(tmp_path, capsys):
    def nan(header, data):
        data[3][header.index("y")] = "nan"
        return header, data
    code, err = _run(_setup(tmp_path, nan), capsys)
    assert code == 2
    assert "ur5_tracker_poses.csv, row 5, field 'y'" in err   # data row 4 is line 5 (header is line 1)


def test_unknown_frame_name(tmp_path, capsys):
    code, err = _run(_setup(tmp_path, config_edit=lambda c: c.replace("frame: tool0", "frame: tool_0")), capsys)
    assert code == 2
    assert "calib.yaml" in err and "measurements[0].frame" in err and "tool0" in err   # suggests the close match


def test_file_that_is_not_urdf(tmp_path, capsys):
    (tmp_path / "arm.urdf").write_text("<html><body>not a robot</body></html>")
    code, err = _run(_setup(tmp_path, config_edit=lambda c: c.replace("example: ur5", "urdf: arm.urdf")), capsys)
    assert code == 2
    assert "arm.urdf" in err and "not a URDF" in err and "<html>" in err


def test_broken_xml(tmp_path, capsys):
    (tmp_path / "arm.urdf").write_text("<robot name='x'>\n<link name='a'>\n</robot>")
    code, err = _run(_setup(tmp_path, config_edit=lambda c: c.replace("example: ur5", "urdf: arm.urdf")), capsys)
    assert code == 2
    assert "arm.urdf: not valid XML at line 3" in err and "row" not in err


def test_millimetres_in_a_metre_column(tmp_path, capsys):
    def to_mm(header, data):
        for r in data:
            for c in ("x", "y", "z"):
                r[header.index(c)] = str(float(r[header.index(c)]) * 1000)
        return header, data
    code, err = _run(_setup(tmp_path, to_mm), capsys)
    assert code == 2
    assert "ur5_tracker_poses.csv, row" in err and "looks like millimetres" in err and "field '" in err


def test_millimetres_accepted_when_declared(tmp_path, capsys):
    def to_mm(header, data):
        for r in data:
            for c in ("x", "y", "z"):
                r[header.index(c)] = str(float(r[header.index(c)]) * 1000)
        return header, data
    cfg = _setup(tmp_path, to_mm, config_edit=lambda c: c.replace("csv: ur5_tracker_poses.csv",
                                                                  "csv: ur5_tracker_poses.csv\n  units: {length: mm}"))
    assert main(["calibrate", str(cfg), "-q"]) == 0


def test_too_few_measurements_for_the_parameters(tmp_path, capsys):
    code, err = _run(_setup(tmp_path, n_rows=5), capsys)
    assert code == 2
    assert "30 measurement rows cannot determine 54 free parameters" in err and "ur5_tracker_poses.csv" in err


def test_unknown_config_key_is_named(tmp_path, capsys):
    code, err = _run(_setup(tmp_path, config_edit=lambda c: c.replace("measurements:", "measurments:")), capsys)
    assert code == 2
    assert "measurments" in err and "did you mean 'measurements'" in err
