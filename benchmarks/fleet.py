"""Benchmark: a fleet of 200 simulated UR5 units (30 tracker poses each) calibrated on Dask, against the same
units split over plain processes (multiprocessing, no Dask), in the same run.

    OMP_NUM_THREADS=1 python benchmarks/fleet.py [--units 200] [--samples 30] [--repeats 5] [--workers 2]

Two comparisons, each like for like:
- started: the Dask cluster and the process pool are started and warmed up (robocal imported in every
  worker) before the clock; `fleet run` on the running cluster (`--scheduler`), with batches of units per task
  (robocal.estimation.parallel_map.batch_size) and, as it was before, one unit per task;
- from cold: the clock includes starting the pool or the LocalCluster (`fleet run --workers N`).
Each repeat runs every way once, in turn (the order rotates between repeats), on a fresh output folder;
the table gives the median of the repeats. The per-task overhead that batch_size weighs is measured at the
end: 400 empty tasks, one at a time per task, on the started cluster. Paste the tables into docs/fleet.md.
"""
import argparse
import os
import statistics
import tempfile
import time
from multiprocessing import get_context
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import yaml  # noqa: E402

from robocal.estimation import parallel_map  # noqa: E402
from robocal.estimation.parallel_map import WORKER_ENV, batch_size, dask_client  # noqa: E402
from robocal.workflows.fleet.manifest import load_fleet  # noqa: E402
from robocal.workflows.fleet.runner import run_fleet  # noqa: E402
from robocal.workflows.fleet.synthetic import simulated_fleet  # noqa: E402
from robocal.workflows.fleet.table import read_table  # noqa: E402
from robocal.workflows.fleet.unit import calibrate_unit  # noqa: E402


def fleet_copy(fleet_yaml: Path, out: str) -> Path:
    """The same fleet writing to its own output folder."""
    raw = yaml.safe_load(fleet_yaml.read_text())
    raw["output"] = {"dir": out, "table": "fleet.parquet"}
    path = fleet_yaml.with_name(f"fleet_{out}.yaml")
    path.write_text(yaml.safe_dump(raw))
    return path


def calibrate_all(jobs) -> list[dict]:
    return [calibrate_unit(job) for job in jobs]


def nothing(x):
    return x


def pool_run(pool, jobs, workers: int) -> list[dict]:
    parts = [jobs[k::workers] for k in range(workers)]
    return [r for part in pool.map(calibrate_all, parts) for r in part]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--units", type=int, default=200)
    ap.add_argument("--samples", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    W = args.workers
    load = os.getloadavg()
    ctx = get_context("spawn")
    times: dict[str, list] = {}
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        fleet = simulated_fleet(tmp, args.units, samples=args.samples, seed=7)
        print(f"simulated {args.units} units of {args.samples} poses in {time.perf_counter() - t0:.1f} s "
              f"(os.cpu_count() = {os.cpu_count()})\n")
        spec = load_fleet(fleet.fleet_yaml)
        os.environ.update(WORKER_ENV)          # the pool's processes as the cluster's workers
        with ctx.Pool(W) as pool, dask_client(workers=W) as client:
            pool.map(calibrate_all, [spec.jobs[k:k + 1] for k in range(W)])    # imports, before any clock
            client.run(lambda: __import__("robocal.workflows.fleet.unit"))
            address = client.scheduler.address

            def dask_started(rep, batched=True):
                overhead = parallel_map.TASK_OVERHEAD_S
                parallel_map.TASK_OVERHEAD_S = overhead if batched else 0.0      # 0: one unit per task
                try:
                    run = run_fleet(fleet_copy(fleet.fleet_yaml, f"d{int(batched)}_{rep}"), scheduler=address)
                finally:
                    parallel_map.TASK_OVERHEAD_S = overhead
                return read_table(run.table_path)

            def pool_cold(rep):
                with ctx.Pool(W) as cold:
                    return pool_run(cold, load_fleet(fleet_copy(fleet.fleet_yaml, f"pc{rep}")).jobs, W)

            ways = {
                "one by one, this process": lambda rep: calibrate_all(
                    load_fleet(fleet_copy(fleet.fleet_yaml, f"s{rep}")).jobs),
                f"{W} plain processes (started)": lambda rep: pool_run(
                    pool, load_fleet(fleet_copy(fleet.fleet_yaml, f"p{rep}")).jobs, W),
                f"fleet run, {W} workers, batched (started)": lambda rep: dask_started(rep, True),
                f"fleet run, {W} workers, 1 unit a task (started)": lambda rep: dask_started(rep, False),
                f"{W} plain processes (from cold)": pool_cold,
                f"fleet run --workers {W} (from cold)": lambda rep: read_table(run_fleet(
                    fleet_copy(fleet.fleet_yaml, f"c{rep}"), workers=W).table_path),
            }
            names = list(ways)
            for rep in range(args.repeats):
                for name in names[rep % len(names):] + names[:rep % len(names)]:
                    t0 = time.perf_counter()
                    rows = ways[name](rep)
                    wall = time.perf_counter() - t0
                    times.setdefault(name, []).append((wall, sum(r["status"] == "converged" for r in rows),
                                                       statistics.mean(r["elapsed_s"] for r in rows)))
            # Dask's own cost per task: empty tasks, one at a time, on the same running cluster
            n_empty = 400
            t0 = time.perf_counter()
            client.gather([client.submit(nothing, k, pure=False) for k in range(n_empty)])
            overhead = (time.perf_counter() - t0) * W / n_empty
    print(f"{'how':<48}{'units':>6}{'converged':>10}{'wall s':>8}{'ms / unit':>10}{'fit ms':>8}"
          f"{'vs plain':>10}")
    med = {k: (statistics.median(w for w, _, _ in v), v[0][1], statistics.median(f for _, _, f in v))
           for k, v in times.items()}
    for name in names:
        wall, ok, fit = med[name]
        ref = med[f"{W} plain processes ({'from cold' if 'cold' in name else 'started'})"][0]
        print(f"{name:<48}{args.units:>6}{ok:>10}{wall:>8.2f}{1e3 * wall / args.units:>10.1f}{1e3 * fit:>8.1f}"
              f"{100 * ref / wall:>9.0f}%")
    unit = med["one by one, this process"][2]
    print(f"\nmedians of {args.repeats} runs of each way (ways in turn, order rotated between repeats); fit ms: one "
          f"unit's calibrate_unit\nwhere it ran; vs plain: the plain processes' wall time over this way's (like for "
          f"like: started or from cold)\nDask's cost per task (400 empty tasks on the started cluster): "
          f"{1e3 * overhead:.1f} ms per task per worker;\nbatch_size for {1e3 * unit:.0f} ms units with that "
          f"overhead: {batch_size(unit, args.units, W, overhead)} (with the constant TASK_OVERHEAD_S = "
          f"{1e3 * parallel_map.TASK_OVERHEAD_S:.0f} ms: {batch_size(unit, args.units, W)})\n"
          f"load average (1 min) before / after: {load[0]:.1f} / {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
