"""Bad input: a clear error naming file, row and field; exit code 2; no output written; no traceback.

The corpus in tests/bad_inputs/ holds one case per folder: calib.yaml (+ data.csv, arm.urdf) and
expected.yaml (the command and the message fragments the error must contain). Add a case by adding a
folder; this one parametrised test runs them all. A case with `exit: 0` is usable input that gets a note
(a byte-order mark stripped, repeated rows): the fragments are in the notes and the command goes on; `bare:
true` runs a command that writes no folder (cv) without -o / -q.
"""
import csv
import shutil
from pathlib import Path

import pytest
import yaml

from robocal.cli.main import main

DEMO = Path(__file__).parents[1] / "robocal" / "io" / "demo"
CORPUS = Path(__file__).parent / "bad_inputs"
CASES = sorted(p.name for p in CORPUS.iterdir() if (p / "expected.yaml").is_file())


@pytest.mark.parametrize("case", CASES)
def test_bad_input_corpus(case, tmp_path, capfd):
    folder = tmp_path / case
    shutil.copytree(CORPUS / case, folder)
    expected = yaml.safe_load((folder / "expected.yaml").read_text())
    out = tmp_path / "out"
    options = [] if expected.get("bare") else ["-o", str(out), "-q"]
    if expected.get("exit", 2) == 0:
        options.append("--no-report")
    code = main([expected["command"], str(folder / "calib.yaml"), *options, *expected.get("args", [])])
    captured = capfd.readouterr()          # file-descriptor level: C++ (urdfdom) lines would show here
    err = captured.err
    assert "Traceback" not in err + captured.out
    if expected.get("exit", 2) == 0:       # usable input: a note, and the command goes on
        assert code == 0, err
        notes = [line for line in err.splitlines() if line.startswith("robocal: note: ")]
        for fragment in expected["contains"]:
            assert any(fragment in line for line in notes), f"{fragment!r} not in the notes {notes!r}"
        assert (out / "result.json").is_file()
        return
    assert code == 2, err
    assert err.startswith("robocal: error: ") and err.count("\n") == 1, f"one line, robocal's own:\n{err}"
    for fragment in expected["contains"]:
        assert fragment in err, f"{fragment!r} not in {err!r}"
    assert not out.exists() and not list(tmp_path.glob(".out*")), "no output (nor temporary folder) on bad input"


def test_corpus_covers_the_issue_cases():
    """Every case of the issue (docs/config.md, bad input) and of the project's standards has a folder."""
    assert {"urdf_truncated", "urdf_joint_without_child", "missing_joint_column", "nan_cell", "metres_declared_mm",
            "millimetres_declared_m", "unreachable_strut_lengths", "too_few_poses", "sigma_misspelt_subkey",
            "sigma_negative", "header_only", "unknown_measurement_type", "misspelt_plan_key",
            "misspelt_simulation_key", "misspelt_iso9283_key",
            # issue 32: inputs handled silently or with the wrong reason before
            "sigma_wrong_dimension", "sigma_larger_than_robot", "weight_negative", "repeated_rows",
            "cv_metres_declared_mm", "centimetres_declared_mm", "inches_declared_mm", "quaternion_scalar_first",
            "joint_beyond_limits", "joint_column_twice", "byte_order_mark", "radians_declared_deg",
            "urdf_kinematic_loop", "urdf_two_parents",
            # issue 36: camera blocks
            "camera_corner_not_on_target", "camera_too_few_corners", "camera_pixel_outside_image",
            "camera_intrinsics_in_mm", "camera_target_seen_from_behind"} <= set(CASES)


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


def _to_mm(header, data):
    for r in data:
        for c in ("x", "y", "z"):
            r[header.index(c)] = str(float(r[header.index(c)]) * 1000)
    return header, data


def test_file_that_is_not_urdf(tmp_path, capsys):
    (tmp_path / "arm.urdf").write_text("<html><body>not a robot</body></html>")
    code = main(["calibrate", str(_setup(tmp_path, config_edit=lambda c: c.replace("example: ur5", "urdf: arm.urdf"))),
                 "-q"])
    err = capsys.readouterr().err
    assert code == 2 and "arm.urdf" in err and "not a URDF" in err and "<html>" in err
    assert not (tmp_path / "robocal-output").exists()


def test_millimetres_accepted_when_declared(tmp_path):
    cfg = _setup(tmp_path, _to_mm, config_edit=lambda c: c.replace(
        "csv: ur5_tracker_poses.csv", "csv: ur5_tracker_poses.csv\n  units: {length: mm}").replace(
        "position: 5.0e-5", "position: 0.05"))           # sigma in the data's unit: 0.05 mm
    assert main(["calibrate", str(cfg), "-q", "--no-report"]) == 0


def test_units_mix_up_goes_on_with_allow_failed(tmp_path, capsys):
    """--allow-failed turns the units stop into a warning printed before the fit."""
    cfg = _setup(tmp_path, config_edit=lambda c: c.replace("csv: ur5_tracker_poses.csv",
                                                          "csv: ur5_tracker_poses.csv\n  units: {length: mm}"))
    main(["calibrate", str(cfg), "-q", "--no-report", "--allow-failed"])
    err = capsys.readouterr().err
    assert "warning" in err and "the data look like metres; the config says mm" in err
    assert (tmp_path / "robocal-output" / "result.json").is_file()
