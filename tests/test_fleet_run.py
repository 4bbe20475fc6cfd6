"""Fleet calibration on a real Dask LocalCluster of 2 worker processes (docs/fleet.md).

20 simulated UR5 units of 30 tracker poses each, each with its own true parameters: U003 has a
broken CSV cell, U007 has its measurements out of step with its joint readings (the fit cannot
converge), U011 has a true elbow offset of 20 mrad where the others lie within +-3.5 mrad.
"""
import os
import shutil
import signal

import numpy as np
import pytest
import yaml

pytest.importorskip("dask.distributed")   # the [fleet] extra; the [test] extra installs it (never skipped in CI)
pytest.importorskip("pyarrow")

from dask.distributed import Client, LocalCluster  # noqa: E402

from robocal.workflows.fleet import runner  # noqa: E402
from robocal.workflows.fleet.manifest import load_fleet  # noqa: E402
from robocal.workflows.fleet.report import fleet_report  # noqa: E402
from robocal.workflows.fleet.synthetic import simulated_fleet  # noqa: E402
from robocal.workflows.fleet.table import read_table  # noqa: E402

N_UNITS, BROKEN, SHUFFLED, FAR = 20, 3, 7, 11
FAR_VALUE = 0.02   # rad; the fleet's perturbation is uniform in +-0.0035 rad


@pytest.fixture(scope="module")
def cluster():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c, \
            Client(c) as client:
        yield c, client


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    return simulated_fleet(tmp_path_factory.mktemp("fleet"), N_UNITS, samples=30, seed=1, broken=(BROKEN,),
                           shuffled=(SHUFFLED,), truth={FAR: {"elbow_joint.offset": FAR_VALUE}})


@pytest.fixture(scope="module")
def first_run(cluster, fleet):
    return runner.run_fleet(fleet.fleet_yaml, scheduler=cluster[0].scheduler_address)


def test_every_unit_has_one_row_and_converged_units_recover_their_truth(first_run, fleet):
    rows = read_table(first_run.table_path)
    keys = [j.key for j in load_fleet(fleet.fleet_yaml).jobs]
    assert sorted(r["key"] for r in rows) == sorted(keys) and len(rows) == N_UNITS
    ok = [r for r in rows if r["status"] == "converged"]
    assert len(ok) == N_UNITS - 2
    # Each estimate errs by ~N(0, se^2) with se from the fit's scaled covariance (150 degrees of freedom):
    # 18 units x 30 parameters, P(|z| > 5) = 5.7e-7 each, so a false failure has probability < 3.1e-4.
    worst = 0.0
    for r in ok:
        truth = fleet.truth[r["unit"]]
        names = [k[3:] for k, v in r.items() if k.startswith("se:") and v is not None]
        assert len(names) == 30, r["key"]
        z = np.array([(r[f"est:{n}"] - truth[n]) / r[f"se:{n}"] for n in names])
        worst = max(worst, float(np.abs(z).max()))
        assert np.all(np.abs(z) < 5.0), (r["key"], dict(zip(names, np.round(z, 1))))
        assert r["rms_after:tracker:mm"] < r["rms_before:tracker:mm"] and 0.8 < r["sigma_ratio"] < 1.2
    assert worst > 1.0   # the check compares real errors (the standard errors are not inflated)
    out = fleet.fleet_yaml.parent / "fleet-output" / "units" / ok[0]["key"]
    written = {p.name for p in out.iterdir()}
    assert {"result.json", "summary.txt", "scene.json"} <= written
    assert any(n.endswith("_calibrated.urdf") for n in written)


def test_failures_carry_clear_messages(first_run):
    rows = {r["unit"]: r for r in read_table(first_run.table_path)}
    broken, shuffled = rows[f"U{BROKEN:03d}"], rows[f"U{SHUFFLED:03d}"]
    assert broken["status"] == "input error"
    assert "U003.csv, row 8, field 'x': '0.1O3' is not a number" in broken["message"]
    assert shuffled["status"] in ("not converged", "diverged") and shuffled["message"]
    assert "iterations" in shuffled["message"] or "residual/sigma" in shuffled["message"]
    assert {r["key"] for r in first_run.failures} == {broken["key"], shuffled["key"]}


def test_the_unit_with_a_large_error_is_the_only_outlier(first_run):
    rep = fleet_report(read_table(first_run.table_path))
    # The others' elbow offsets are uniform in +-3.5 mrad: MAD about 1.75 mrad, robust sd about 2.6 mrad,
    # so the farthest normal unit sits near 1.4 sd and the 20 mrad unit near 7 sd, past the threshold of 5.
    assert [o.unit for o in rep.outliers] == [f"U{FAR:03d}"]
    assert "elbow_joint.offset" in [p[0] for p in rep.outliers[0].parameters]


def test_a_rerun_does_no_work(first_run, fleet, monkeypatch):
    before = first_run.table_path.read_bytes()

    def no_cluster(*args, **kwargs):
        raise AssertionError("a re-run of a finished fleet started a cluster")

    monkeypatch.setattr(runner, "dask_client", no_cluster)
    again = runner.run_fleet(fleet.fleet_yaml)
    assert (again.skipped, again.calibrated) == (N_UNITS, 0)
    assert first_run.table_path.read_bytes() == before


def test_killing_a_worker_during_a_run_loses_no_unit(cluster, fleet, monkeypatch):
    cl, client = cluster
    monkeypatch.setattr(runner, "FLUSH_SECONDS", 0.0)    # write the table after every unit,
    monkeypatch.setattr(runner, "WRITE_SHARE", float("inf"))   # however long a write takes
    seen = []
    raw = yaml.safe_load(fleet.fleet_yaml.read_text())
    raw["output"] = {"dir": "fleet-output-kill", "table": "fleet.parquet"}
    second = fleet.fleet_yaml.with_name("fleet_kill.yaml")
    second.write_text(yaml.safe_dump(raw))
    killed = []

    def kill_one_worker(done, total, row):
        seen.append((done, len(read_table(second.parent / "fleet-output-kill" / "fleet.parquet"))))
        if not killed:
            pids = client.run(os.getpid)          # {worker address: pid}
            victim = sorted(pids)[0]
            os.kill(pids[victim], signal.SIGKILL)
            killed.append(victim)

    run = runner.run_fleet(second, scheduler=cl.scheduler_address, progress=kill_one_worker)
    assert killed and run.calibrated == N_UNITS
    assert all(done == in_table for done, in_table in seen)   # rows streamed to the table as units finish
    rows = read_table(run.table_path)
    assert len(rows) == N_UNITS and len({r["key"] for r in rows}) == N_UNITS
    assert sum(r["status"] == "converged" for r in rows) == N_UNITS - 2
    shutil.rmtree(fleet.fleet_yaml.parent / "fleet-output-kill")


def test_the_table_is_rewritten_less_often_once_a_rewrite_takes_long():
    """flush_interval: every FLUSH_SECONDS while a rewrite is quick; once it is not, rewrites take WRITE_SHARE
    of the time (a whole-table rewrite grows with the fleet: 0.3 s at 10000 rows)."""
    assert runner.flush_interval(0.008) == runner.FLUSH_SECONDS == 1.0
    assert runner.flush_interval(0.3) == pytest.approx(0.3 / runner.WRITE_SHARE) == pytest.approx(15.0)


def sleepy_square(x):
    import time
    time.sleep(0.02)
    return x * x


def test_items_travel_in_batches_and_come_back_once_each(cluster):
    """40 items of 20 ms with a 10 ms per-task cost: fewer tasks than items, every result once, in order."""
    from dask.distributed import get_task_stream
    from robocal.estimation.parallel_map import completed, map_tasks
    cl, client = cluster
    with get_task_stream(client) as stream:
        seen = sorted((i, r) for i, r, exc in completed(client, sleepy_square, list(range(40))) if exc is None)
    assert seen == [(i, i * i) for i in range(40)]
    tasks = [t for t in stream.data if "Batch" in str(t.get("key"))]
    assert 4 < len(tasks) < 30, len(tasks)            # single items first, then batches of several
    assert map_tasks(sleepy_square, range(10), scheduler=cl.scheduler_address) == [i * i for i in range(10)]


def test_a_running_client_is_used_as_it_is_and_left_open(cluster):
    """scheduler=<Client>: no second connection (dask_client yields that Client), and it is not closed after."""
    from robocal.estimation.parallel_map import dask_client, map_tasks
    cl, client = cluster
    with dask_client(client) as used:
        assert used is client
    assert map_tasks(sleepy_square, range(6), scheduler=client) == [i * i for i in range(6)]
    assert client.status == "running" and client.submit(sleepy_square, 3).result() == 9


def noisy_mean(rng):
    return float(rng.normal(size=50).mean())


@pytest.mark.parametrize("batch", [1, 4, 13])
def test_results_do_not_depend_on_the_batch_size(cluster, monkeypatch, batch):
    """Seeded repetitions on the cluster, 1, 4 or 13 to a task (tasks finish in any order on 2 workers): the
    serial run's results, bit for bit, in input order."""
    from robocal.estimation import parallel_map
    monkeypatch.setattr(parallel_map, "batch_size", lambda *args, **kwargs: batch)
    serial = parallel_map.monte_carlo(noisy_mean, 30, seed=5)
    assert parallel_map.monte_carlo(noisy_mean, 30, seed=5, scheduler=cluster[0].scheduler_address) == serial
    assert len(set(serial)) == 30       # each repetition its own stream


def test_robocal_local_cluster_settings_reach_the_workers():
    """LOCAL_CONFIG (less periodic work beside the tasks) holds in the workers, not only in the client."""
    import dask.config
    from robocal.estimation.parallel_map import LOCAL_CONFIG, dask_client
    import os
    with dask_client(workers=1) as client:
        seen = client.run(lambda: {k: dask.config.get(k) for k in LOCAL_CONFIG})
        trim = client.run(lambda: os.environ.get("MALLOC_TRIM_THRESHOLD_"))
    assert list(seen.values()) == [LOCAL_CONFIG]
    assert list(trim.values()) == [os.environ.get("MALLOC_TRIM_THRESHOLD_")]   # glibc's own, as in the client


def frozen_objects(_):
    import gc
    return gc.get_freeze_count()


def test_a_worker_freezes_its_heap_after_its_first_task_and_the_caller_never():
    """parallel_map.freeze_heap: a worker's first task runs on the heap as it is, every later one finds the
    objects alive then in the permanent generation; a Batch run in the process that made it freezes nothing."""
    import gc
    from robocal.estimation.parallel_map import Batch, completed
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as one, \
            Client(one) as solo:
        counts = sorted(r for _, r, exc in completed(solo, frozen_objects, list(range(6))))
    assert counts[0] == 0 and counts[1] > 10_000, counts     # one first task; the worker's modules and state
    before = gc.get_freeze_count()
    assert Batch(frozen_objects)([0, 1]) and gc.get_freeze_count() == before


def test_plan_curve_on_the_cluster_equals_the_serial_run(cluster, tmp_path):
    from robocal.workflows.plan import plan_from_config, prediction_dict

    config = {"robot": {"example": "ur5"}, "data": {"csv": "not_measured_yet.csv"},
              "parameters": {"preset": "full", "frames": {"tool0": True}, "base": True},
              "measurements": [{"type": "pose", "name": "tracker", "frame": "tool0",
                                "columns": ["x", "y", "z", "qx", "qy", "qz", "qw"]}],
              "plan": {"N": 12, "seed": 4, "candidates": {"count": 80}, "validation": 20, "curve": [8, 12, 16, 24]}}
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(config))
    serial = prediction_dict(plan_from_config(path))
    spread = prediction_dict(plan_from_config(path, scheduler=cluster[0].scheduler_address))
    assert [c["n_poses"] for c in spread["curve"]] == [8, 12, 16, 24]
    assert spread == serial      # bit for bit: each curve point is a deterministic task


def test_fleet_run_command_on_its_own_local_cluster(tmp_path, capsys):
    from robocal.cli.main import main

    small = simulated_fleet(tmp_path, 3, samples=30, seed=2, broken=(1,))
    assert main(["fleet", "run", str(small.fleet_yaml), "--workers", "1", "-q"]) == 3   # 3: a unit failed
    out = capsys.readouterr().out
    assert "3 units: 0 already in the table, 3 calibrated (2 converged, 1 input error)" in out
    assert "U001_2026-01-15: input error:" in out and "U001.csv, row 8, field 'x'" in out
    assert main(["fleet", "run", str(small.fleet_yaml), "-q"]) == 0
    assert "3 units: 3 already in the table, 0 calibrated" in capsys.readouterr().out
