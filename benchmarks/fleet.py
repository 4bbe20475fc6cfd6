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
import resource
import statistics
import tempfile
import time
from multiprocessing import get_context
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import psutil  # noqa: E402  (a dependency of dask.distributed)
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


def cpu_seconds() -> float:
    """CPU time (user + system) of this process and all its children, live or ended: a way's difference of
    it is the CPU that all its processes used (workers, nannies, scheduler, client, pool), whatever the load
    of other jobs on the machine did to its wall time."""
    me = psutil.Process()
    t = me.cpu_times()
    total = t.user + t.system
    ended = resource.getrusage(resource.RUSAGE_CHILDREN)
    total += ended.ru_utime + ended.ru_stime
    for child in me.children(recursive=True):
        try:
            c = child.cpu_times()
            total += c.user + c.system
        except psutil.NoSuchProcess:
            pass
    return total


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
            # imports and first calls (the example robot's URDF, caches), before any clock, in both
            pool.map(calibrate_all, [spec.jobs[k:k + 1] for k in range(W)])
            client.gather([client.submit(calibrate_all, spec.jobs[k:k + 1], workers=[w], pure=False)
                           for k, w in enumerate(sorted(client.scheduler_info()["workers"]))])
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
                    t0, c0 = time.perf_counter(), cpu_seconds()
                    rows = ways[name](rep)
                    wall, cpu = time.perf_counter() - t0, cpu_seconds() - c0
                    times.setdefault(name, []).append((wall, sum(r["status"] == "converged" for r in rows),
                                                       statistics.mean(r["elapsed_s"] for r in rows), cpu))
            # Dask's own cost per task: empty tasks, one at a time, on the same running cluster
            n_empty = 400
            t0 = time.perf_counter()
            client.gather([client.submit(nothing, k, pure=False) for k in range(n_empty)])
            overhead = (time.perf_counter() - t0) * W / n_empty
    print(f"{'how':<48}{'converged':>10}{'wall s':>8}{'fit ms':>8}{'CPU s':>8}{'vs plain: wall':>16}{'CPU':>6}")
    med = {k: (statistics.median(w for w, _, _, _ in v), v[0][1], statistics.median(f for _, _, f, _ in v),
               statistics.median(c for _, _, _, c in v)) for k, v in times.items()}
    for name in names:
        wall, ok, fit, cpu = med[name]
        ref = times[f"{W} plain processes ({'from cold' if 'cold' in name else 'started'})"]
        # the median over repeats of (plain / this way) within each repeat: slow drifts of the machine's load
        # cancel in each ratio
        r_wall = statistics.median(p[0] / t[0] for p, t in zip(ref, times[name]))
        r_cpu = statistics.median(p[3] / t[3] for p, t in zip(ref, times[name]))
        print(f"{name:<48}{ok:>10}{wall:>8.2f}{1e3 * fit:>8.1f}{cpu:>8.2f}{100 * r_wall:>15.0f}%{100 * r_cpu:>5.0f}%")
    unit = med["one by one, this process"][2]
    print(f"\n{args.units} units; medians of {args.repeats} runs of each way (ways in turn, order rotated between "
          f"repeats); fit ms: one unit's\ncalibrate_unit where it ran; vs plain: median over the repeats of the plain processes' wall (CPU) time "
          f"over\nthis way's in the same repeat, like for like (started or from cold); CPU s: all processes of the way (workers, "
          f"nannies, scheduler, client, pool)\nDask's cost per task (400 empty tasks on the started cluster): "
          f"{1e3 * overhead:.1f} ms per task per worker;\nbatch_size for {1e3 * unit:.0f} ms units with that "
          f"overhead: {batch_size(unit, args.units, W, overhead)} (with the constant TASK_OVERHEAD_S = "
          f"{1e3 * parallel_map.TASK_OVERHEAD_S:.0f} ms: {batch_size(unit, args.units, W)})\n"
          f"load average (1 min) before / after: {load[0]:.1f} / {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
