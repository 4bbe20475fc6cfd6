"""benchmarks/figaroh_env.py, without installing FIGAROH: the skip path, the child environment, and a driver
failure reported with its error output (the installs and the comparisons themselves are benchmarks)."""
import argparse
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import figaroh_env  # noqa: E402


def parse(argv):
    ap = argparse.ArgumentParser()
    figaroh_env.add_options(ap)
    return ap.parse_args(argv)


def test_without_the_flag_nothing_is_installed_and_the_skip_says_how(tmp_path, capsys):
    venv = tmp_path / "venv"
    assert figaroh_env.figaroh_python(parse(["--figaroh-venv", str(venv)])) is None
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and "FIGAROH skipped" in out and "--figaroh" in out
    assert not venv.exists()


def test_the_driver_runs_without_robocal_import_path_and_on_one_thread(monkeypatch):
    monkeypatch.setenv("PYTHONPATH", "/somewhere/robocal")
    monkeypatch.setenv("OMP_NUM_THREADS", "4")
    env = figaroh_env.child_env()
    assert "PYTHONPATH" not in env and env["OMP_NUM_THREADS"] == "1"


def test_a_failing_driver_raises_with_its_error_output(tmp_path, monkeypatch):
    (tmp_path / "broken.py").write_text("import sys\nsys.exit('driver says no')\n")
    monkeypatch.setattr(figaroh_env, "DRIVERS", tmp_path)
    with pytest.raises(RuntimeError, match="driver says no"):
        figaroh_env.run_driver(Path(sys.executable), "broken.py", {"x": 1})


def test_a_driver_answer_comes_back_with_its_wall_time(tmp_path, monkeypatch):
    (tmp_path / "echo.py").write_text("import json, sys\nr = json.load(open(sys.argv[1]))\n"
                                      "json.dump({'twice': 2 * r['x']}, open(r['result'], 'w'))\n")
    monkeypatch.setattr(figaroh_env, "DRIVERS", tmp_path)
    answer, seconds = figaroh_env.run_driver(Path(sys.executable), "echo.py", {"x": 21})
    assert answer == {"twice": 42} and seconds > 0
