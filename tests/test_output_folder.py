"""Output folders: written whole or not at all, with a manifest; --force replaces only robocal's own folder."""
import json
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.errors import InputError
from robocal.io.output_folder import MANIFEST, add_to_manifest, write_folder

DEMO = Path(__file__).parents[1] / "robocal" / "io" / "demo" / "ur5_calibrate.yaml"


def test_a_folder_lists_what_robocal_wrote_and_force_replaces_it(tmp_path):
    out = tmp_path / "out"
    write_folder(out, {"a.txt": b"1", "b.txt": b"2"})
    assert json.loads((out / MANIFEST).read_text())["files"] == ["a.txt", "b.txt"]
    with pytest.raises(InputError, match="pass --force"):
        write_folder(out, {"c.txt": b"3"})
    write_folder(out, {"c.txt": b"3"}, force=True)
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "c.txt"]
    assert not [p for p in tmp_path.iterdir() if p.name != "out"], "no temporary folder left beside it"


def test_force_refuses_a_folder_with_files_robocal_did_not_write(tmp_path):
    out = tmp_path / "out"
    write_folder(out, {"result.json": b"{}"})
    (out / "my_notes.txt").write_text("keep me")
    with pytest.raises(InputError, match="did not write.*my_notes.txt") as exc:
        write_folder(out, {"result.json": b"{}"}, force=True)
    assert exc.value.source == str(out.resolve())
    assert (out / "my_notes.txt").read_text() == "keep me" and (out / "result.json").is_file()


def test_force_refuses_a_folder_robocal_did_not_write(tmp_path):
    out = tmp_path / "thesis"
    out.mkdir()
    (out / "chapter1.tex").write_text("precious")
    with pytest.raises(InputError, match=f"no {MANIFEST}"):
        write_folder(out, {"result.json": b"{}"}, force=True)
    assert (out / "chapter1.tex").read_text() == "precious"


def test_a_failure_while_writing_leaves_nothing(tmp_path, monkeypatch):
    calls = []
    real = Path.write_bytes

    def failing(self, data):
        calls.append(self.name)
        if len(calls) == 2:
            raise OSError("disk full")
        return real(self, data)
    monkeypatch.setattr(Path, "write_bytes", failing)
    with pytest.raises(OSError):
        write_folder(tmp_path / "out", {"a": b"1", "b": b"2"})
    assert not list(tmp_path.iterdir())


def test_calibrate_force_keeps_a_users_folder_and_says_why(tmp_path, capsys):
    """`--force -o FOLDER` used to delete the whole folder, files robocal did not write included."""
    out = tmp_path / "results"
    out.mkdir()
    (out / "measurements_2026.csv").write_text("x\n1\n")
    code = main(["calibrate", str(DEMO), "-o", str(out), "--force", "-q"])
    err = capsys.readouterr().err
    assert code == 2 and "--force replaces only a folder robocal wrote" in err and str(out) in err
    assert [p.name for p in out.iterdir()] == ["measurements_2026.csv"]


def test_plan_force_keeps_a_users_folder(tmp_path, capsys):
    out = tmp_path / "plan"
    out.mkdir()
    (out / "poses_by_hand.csv").write_text("pose\n1\n")
    assert main(["plan", str(DEMO), "-o", str(out), "--force", "-q"]) == 2
    assert "poses_by_hand.csv" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["poses_by_hand.csv"]


def test_a_report_added_later_is_robocals_too(tmp_path):
    """`robocal report` writes report.html into a result folder: recorded, so --force may replace the folder."""
    out = tmp_path / "out"
    write_folder(out, {"result.json": b"{}"})
    (out / "report.html").write_text("<html></html>")
    add_to_manifest(out / "report.html")
    write_folder(out, {"result.json": b"{}"}, force=True)
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "result.json"]
