"""Property-based fuzzing of the CSV, YAML and URDF readers (hypothesis): whatever a damaged file holds,
the reader either accepts it or raises InputError naming the file and where in it - never another
exception (a traceback for the user) - and writes nothing. Deterministic (derandomize) and ~50 examples
per reader, so it runs in seconds."""
import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robocal.errors import InputError
from robocal.workflows.setup import load_config
from robocal.model.robot import load_urdf

ROOT = Path(__file__).parents[1]
DEMO = ROOT / "robocal" / "io" / "demo"
CSV_TEXT = b"".join((DEMO / "ur5_tracker_poses.csv").read_bytes().splitlines(keepends=True)[:6])
YAML_TEXT = (DEMO / "ur5_calibrate.yaml").read_bytes()
URDF_TEXT = b"""<?xml version="1.0"?>
<robot name="two_links">
  <link name="base"/>
  <link name="arm"><inertial><mass value="1.0"/><origin xyz="0.1 0 0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="hand"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="arm"/><child link="hand"/>
    <origin xyz="0.4 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="10" velocity="1"/></joint>
</robot>
"""
# what damages files: separators, quotes, brackets, signs, NaN/inf, NUL, a byte that is not UTF-8
PIECES = [b",", b"\n", b'"', b":", b"-", b" ", b"nan", b"inf", b"1e999", b"x", b"<", b">", b"/", b"{", b"[", b"]",
          b"\t", b"\x00", b"\xff", b"#", b"&", b"0", b"'"]
EDITS = st.lists(st.tuples(st.sampled_from(["delete", "insert", "replace", "truncate"]),
                           st.floats(0, 1, allow_nan=False), st.sampled_from(PIECES)), min_size=1, max_size=4)
FUZZ = settings(max_examples=50, derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def damaged(text: bytes, edits) -> bytes:
    for op, where, piece in edits:
        i = int(where * len(text))
        if op == "delete":
            text = text[:i] + text[i + 1 + len(piece):]
        elif op == "insert":
            text = text[:i] + piece + text[i:]
        elif op == "replace":
            text = text[:i] + piece + text[i + len(piece):]
        else:
            text = text[:i]
    return text


def check_reader(read, folder: Path, name: str) -> None:
    before = sorted(p.name for p in folder.iterdir())
    try:
        read()
    except InputError as exc:
        assert exc.source and Path(exc.source).name in {name, "calib.yaml", "data.csv", "arm.urdf"}, str(exc)
        whole_file = any(w in exc.reason for w in ("empty", "not a text file", "not a mapping", "not found"))
        assert exc.field or exc.row or "line" in exc.reason or whole_file, f"says not where: {exc}"
        assert "\n" not in str(exc).strip() or "YAML" in str(exc), str(exc)
    assert sorted(p.name for p in folder.iterdir()) == before, "a reader wrote something"


def _fresh(tmp_path: Path, name: str) -> Path:
    folder = tmp_path / name
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir()
    (folder / "calib.yaml").write_bytes(YAML_TEXT.replace(b"ur5_tracker_poses.csv", b"data.csv"))
    (folder / "data.csv").write_bytes(CSV_TEXT)
    return folder


@FUZZ
@given(edits=EDITS)
def test_csv_reader(tmp_path, edits):
    folder = _fresh(tmp_path, "csv")
    (folder / "data.csv").write_bytes(damaged(CSV_TEXT, edits))
    check_reader(lambda: load_config(folder / "calib.yaml"), folder, "data.csv")


@FUZZ
@given(edits=EDITS)
def test_yaml_reader(tmp_path, edits):
    folder = _fresh(tmp_path, "yaml")
    (folder / "calib.yaml").write_bytes(damaged((folder / "calib.yaml").read_bytes(), edits))
    check_reader(lambda: load_config(folder / "calib.yaml"), folder, "calib.yaml")


@FUZZ
@given(edits=EDITS)
def test_urdf_reader(tmp_path, edits, capfd):
    folder = _fresh(tmp_path, "urdf")
    (folder / "arm.urdf").write_bytes(damaged(URDF_TEXT, edits))
    check_reader(lambda: load_urdf(folder / "arm.urdf"), folder, "arm.urdf")
    assert capfd.readouterr().err == "", "urdfdom printed to the terminal"


def test_the_urdf_seed_file_loads(tmp_path):
    (tmp_path / "arm.urdf").write_bytes(URDF_TEXT)
    assert load_urdf(tmp_path / "arm.urdf").model.nq == 2
