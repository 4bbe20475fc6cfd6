"""Fleet pieces without a cluster: manifest errors, the Parquet table, outliers and drift (docs/fleet.md)."""
import dataclasses

import numpy as np
import pytest
import yaml

pytest.importorskip("pyarrow")   # the [fleet] extra; the [test] extra installs it (never skipped in CI)

from robocal.errors import InputError  # noqa: E402
from robocal.estimation.parallel_map import map_tasks  # noqa: E402
from robocal.workflows.fleet.manifest import load_fleet  # noqa: E402
from robocal.workflows.fleet.report import fleet_report, summary_lines  # noqa: E402
from robocal.workflows.fleet.table import FleetTable, read_table, write_table  # noqa: E402
from robocal.workflows.config_types import MeasurementConfig  # noqa: E402
from robocal.workflows.fleet.unit import FINAL_STATUSES, calibrate_unit, unit_config  # noqa: E402


def write_fleet(tmp_path, manifest: str, **extra):
    (tmp_path / "arm.yaml").write_text(yaml.safe_dump({
        "robot": {"example": "ur5"}, "data": {"csv": "x.csv"},
        "measurements": [{"type": "pose", "frame": "tool0", "columns": ["x", "y", "z", "qx", "qy", "qz", "qw"]}]}))
    (tmp_path / "units.csv").write_text(manifest)
    (tmp_path / "fleet.yaml").write_text(yaml.safe_dump({"config": "arm.yaml", "units": "units.csv", **extra}))
    return tmp_path / "fleet.yaml"


@pytest.mark.parametrize("manifest, where, what", [
    ("unit,data,date\nA,a.csv,2026-01-01\nA,b.csv,2026-01-01\n", "row 3", "listed twice"),
    ("unit,data,date\nA,a.csv,2026-13-01\n", "row 2, field 'date'", "not a date"),
    ("unit,data\nA/B,a.csv\n", "row 2, field 'unit'", "not a unit name"),
    ("unit,file\nA,a.csv\n", "row 1, field 'data'", "missing column"),
])
def test_manifest_errors_name_file_row_and_field(tmp_path, manifest, where, what):
    with pytest.raises(InputError) as err:
        load_fleet(write_fleet(tmp_path, manifest))
    assert "units.csv" in str(err.value) and where in str(err.value) and what in str(err.value)


def test_hashes_follow_inputs_and_config(tmp_path):
    (tmp_path / "a.csv").write_text("1\n")
    path = write_fleet(tmp_path, "unit,data\nA,a.csv\nB,b.csv\n")
    a, b = load_fleet(path).jobs
    assert b.input_hash != a.input_hash and a.key == "A"
    (tmp_path / "a.csv").write_text("2\n")
    a2 = load_fleet(path).jobs[0]
    assert a2.input_hash != a.input_hash and a2.config_hash == a.config_hash
    write_fleet(tmp_path, "unit,data\nA,a.csv\n", accept={"max_sigma_ratio": 3})
    assert load_fleet(path).jobs[0].config_hash != a.config_hash


def test_a_missing_data_file_is_a_row_not_a_crash(tmp_path):
    job = load_fleet(write_fleet(tmp_path, "unit,data\nA,missing.csv\n")).jobs[0]
    row = calibrate_unit(job)
    assert row["status"] == "input error" and "missing.csv" in row["message"] and "not found" in row["message"]


def test_table_round_trip_and_resume_rule(tmp_path):
    rows = [{"key": "A", "unit": "A", "date": "", "status": "converged", "input_hash": "h", "config_hash": "c",
             "iterations": 4, "est:p": 1.5, "se:p": 0.1},
            {"key": "B", "unit": "B", "date": "", "status": "lost", "input_hash": "h", "config_hash": "c",
             "message": "worker died"}]
    path = write_table(tmp_path / "t.parquet", rows)
    back = read_table(path)
    assert back[0]["est:p"] == 1.5 and back[0]["iterations"] == 4 and back[1]["est:p"] is None
    assert not list(tmp_path.glob(".t.parquet.*"))       # the temporary file was moved into place
    table = FleetTable.open(path)

    class Job:
        def __init__(self, key, input_hash="h", config_hash="c"):
            self.key, self.input_hash, self.config_hash = key, input_hash, config_hash

    assert table.is_done(Job("A"), FINAL_STATUSES)
    assert not table.is_done(Job("A", input_hash="new data"), FINAL_STATUSES)
    assert not table.is_done(Job("A", config_hash="new config"), FINAL_STATUSES)
    assert not table.is_done(Job("B"), FINAL_STATUSES)     # lost with its worker: calibrated again
    (tmp_path / "bad.parquet").write_text("not parquet")
    with pytest.raises(InputError, match="bad.parquet: not a Parquet file"):
        read_table(tmp_path / "bad.parquet")


def fleet_rows(rng, n=30, se=1e-4):
    """n units whose parameter p is N(0, 1 mm) across the fleet, estimated with standard error `se`."""
    return [{"key": f"U{i}", "unit": f"U{i}", "date": "2026-01-01", "status": "converged",
             "est:p": float(rng.normal(0, 1e-3)), "se:p": se, "est:q": float(rng.normal(0, 1e-3)), "se:q": se}
            for i in range(n)]


def test_outliers_and_drift():
    rng = np.random.default_rng(5)
    rows = fleet_rows(rng)
    rows[4]["est:q"] = 0.012                                    # 12 sd of the fleet's spread
    # U7 again a year later: p moved by 2 mm (20 combined standard errors of 0.14 mm), q by 0.1 mm (0.7)
    rows.append({**rows[7], "key": "U7_2027", "date": "2027-01-01", "est:p": rows[7]["est:p"] + 2e-3,
                 "est:q": rows[7]["est:q"] + 1e-4})
    rows.append({"key": "U9_2027", "unit": "U9", "date": "2027-01-01", "status": "not converged", "message": "m"})
    rep = fleet_report(rows)
    # Normal spread of 1 mm over 31 rows: |z| > 5 has probability 5.7e-7 per value, so only U4 is flagged.
    assert [(o.key, [p[0] for p in o.parameters]) for o in rep.outliers] == [("U4", ["q"])]
    assert rep.outliers[0].parameters[0][3] == pytest.approx(12, rel=0.35)     # robust sd of 31 draws: +-30 %
    assert [(d.unit, d.parameter) for d in rep.drifts] == [("U7", "p")]
    assert rep.drifts[0].z == pytest.approx(2e-3 / np.hypot(1e-4, 1e-4))
    assert rep.drifts[0].per_year == pytest.approx(2e-3 * 365.25 / 365)
    assert rep.statuses == {"converged": 31, "not converged": 1} and rep.failures[0]["key"] == "U9_2027"
    text = "\n".join(summary_lines(rep))
    assert "OUTLIER U4: q" in text and "DRIFT U7 p" in text and "FAILED U9_2027" in text


def test_a_fleet_more_alike_than_its_estimates_flags_nobody():
    rng = np.random.default_rng(6)
    rows = fleet_rows(rng, se=1e-2)     # spread 1 mm, but each estimate only good to 10 mm
    rows[0]["est:p"] = 0.02             # 20 sd of the spread, 2 standard errors
    assert fleet_report(rows).outliers == []


def test_map_tasks_in_process_keeps_the_order():
    assert map_tasks(lambda x: x * x, range(5)) == [0, 1, 4, 9, 16]


def test_fleet_page(tmp_path):
    pytest.importorskip("matplotlib")
    from robocal.workflows.fleet.page import fleet_page

    rows = fleet_rows(np.random.default_rng(5))
    rows[4]["est:q"] = 0.012
    rows.append({**rows[7], "key": "U7_2027", "date": "2027-01-01", "est:p": rows[7]["est:p"] + 2e-3})
    page = fleet_page(fleet_report(rows))
    assert page.startswith("<!DOCTYPE html>") and page.count("data:image/png;base64,") == 2
    assert '<table class="outliers">' in page and "<td>U4</td>" in page and '<table class="drift">' in page


def test_glob_units_and_per_unit_files(tmp_path):
    (tmp_path / "data").mkdir()
    for name in ("B", "A"):
        (tmp_path / "data" / f"{name}.csv").write_text("x\n")
    path = write_fleet(tmp_path, "")
    raw = yaml.safe_load(path.read_text())
    path.write_text(yaml.safe_dump({**raw, "units": {"glob": "data/*.csv"}}))
    jobs = load_fleet(path).jobs
    assert [j.key for j in jobs] == ["A", "B"] and jobs[0].data[""] == str(tmp_path / "data" / "A.csv")
    # a manifest row with its own URDF and a second data file for blocks that read `csv: plane.csv`
    (tmp_path / "units.csv").write_text("unit,data,data:plane.csv,urdf,date\nC,c.csv,c_plane.csv,c.urdf,2026-02-03\n")
    path.write_text(yaml.safe_dump(raw))
    job = load_fleet(path).jobs[0]
    plane = MeasurementConfig("plane", "plane1", "tool0", "measurements[1]", csv=job.config.base_dir / "plane.csv")
    job = dataclasses.replace(job, config=dataclasses.replace(job.config,
                                                              measurements=(*job.config.measurements, plane)))
    cfg = unit_config(job)
    assert cfg.data.csv == tmp_path / "c.csv" and cfg.measurements[1].csv == tmp_path / "c_plane.csv"
    assert cfg.robot.urdf == tmp_path / "c.urdf" and job.key == "C_2026-02-03"
    assert cfg.output.dir == tmp_path / "fleet-output" / "units" / "C_2026-02-03"


def test_fleet_report_command(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    from robocal.cli.main import main

    rows = fleet_rows(np.random.default_rng(5))
    rows[4]["est:q"] = 0.012
    table = write_table(tmp_path / "fleet.parquet", rows)
    assert main(["fleet", "report", str(table)]) == 0
    out = capsys.readouterr().out
    assert "30 calibrations: 30 converged" in out and "OUTLIER U4: q" in out
    assert (tmp_path / "fleet.html").read_text().startswith("<!DOCTYPE html>")
    assert main(["fleet", "report", str(tmp_path / "none.parquet")]) == 2
    assert "none.parquet: fleet table not found" in capsys.readouterr().err


def test_batch_size_rule(monkeypatch):
    """Units per Dask task: enough that the per-task cost is at most 2 % of a task, capped by 1 s of work and
    by two tasks per worker of what is left; one while the unit time is unknown."""
    from robocal.estimation import parallel_map
    from robocal.estimation.parallel_map import batch_size
    assert batch_size(None, 200, 2) == 1
    assert batch_size(0.05, 200, 2, overhead_seconds=0.010) == 10           # ceil(0.010 * 0.98 / (0.02 * 0.05))
    assert batch_size(0.005, 2000, 2, overhead_seconds=0.010) == 98         # ceil(97.99..): 490 ms tasks
    assert batch_size(0.002, 10_000, 2, overhead_seconds=0.1) == 500        # capped at 1 s of work
    assert batch_size(0.05, 12, 2, overhead_seconds=0.010) == 3             # the last 12 units: 12 // 4
    assert batch_size(1.0, 200, 2, overhead_seconds=0.010) == 1             # long units: one a task
    assert batch_size(0.03, 200, 2) == 10          # the benchmark's 30 ms units with the 6 ms measured per task
    assert batch_size(0.05, 200, 2, overhead_seconds=0.010, share=0.05) == 4   # ceil(0.010 * 0.95 / (0.05 * 0.05))
    monkeypatch.setattr(parallel_map, "TASK_OVERHEAD_S", 0.0)      # the module's settings are read when called
    assert batch_size(0.03, 200, 2) == 1
