"""Benchmark: a fleet of 200 simulated UR5 units (30 tracker poses each) calibrated on Dask, against the same
units split over plain processes (multiprocessing, no Dask), and against the Dask settings of a baseline commit
(default: main), all in the same run.

    OMP_NUM_THREADS=1 python benchmarks/fleet.py [--units 200] [--samples 30] [--repeats 5] [--workers 2] [--ways W,..]
                                                 [--baseline main]

Like for like:
- started: the process pool, and for each Dask way a LocalCluster with that way's settings, are started and
  warmed up (robocal imported, one real unit run in every worker) before the clock; run_fleet on the running
  cluster, handed its Client ("a second client": handed the scheduler's address instead, as `fleet run
  --scheduler` is, which connects a second Client with its own event-loop thread in this process, where the
  LocalCluster's scheduler runs too). The plain processes get their units in one message each and return rows;
  `fleet run` also writes the fleet table (about 10 ms a write, once a second).
- from cold: the clock includes starting the pool or the LocalCluster (`fleet run --workers N`).
The baseline's settings (LOCAL_CONFIG, TASK_OVERHEAD_S, OVERHEAD_SHARE) are read from its
robocal/estimation/parallel_map.py (git show, ast) and set in this tree's module for its ways (its code is this
tree's: the workers' heap freeze included). "heap not frozen": this tree with the workers' gc.freeze after their
first task (parallel_map.freeze_heap) skipped.
Each repeat runs every way once, in turn (the order rotates between repeats), on a fresh output folder; the
table gives medians of the repeats, and each way's ratio to the plain processes is the median of the per-repeat
ratios (slow drifts of the machine's load cancel). CPU s counts every process of the way (workers, nannies,
scheduler, client, pool); "client CPU" this process's share (client, scheduler and nannies live here).
At the end, Dask's per-task cost as TASK_OVERHEAD_S counts it: the CPU of all processes for 200 spinning
35 ms items sent one per task against 30 per task, on a started cluster of this tree's settings.
"""
import argparse
import ast
import contextlib
import os
import resource
import statistics
import subprocess
import tempfile
import time
from multiprocessing import get_context
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import psutil  # noqa: E402  (a dependency of dask.distributed)
import yaml  # noqa: E402

from robocal.estimation import parallel_map  # noqa: E402
from robocal.estimation.parallel_map import WORKER_ENV, batch_size, completed, dask_client  # noqa: E402
from robocal.workflows.fleet.manifest import load_fleet  # noqa: E402
from robocal.workflows.fleet.runner import run_fleet  # noqa: E402
from robocal.workflows.fleet.synthetic import simulated_fleet  # noqa: E402
from robocal.workflows.fleet.table import read_table  # noqa: E402
from robocal.workflows.fleet.unit import calibrate_unit  # noqa: E402

SETTINGS = ("LOCAL_CONFIG", "TASK_OVERHEAD_S", "OVERHEAD_SHARE")


def settings_at(commit: str) -> dict:
    """The SETTINGS of robocal/estimation/parallel_map.py at `commit` (literal assignments, read with ast)."""
    source = subprocess.run(["git", "-C", os.path.dirname(os.path.abspath(__file__)), "show",
                             f"{commit}:robocal/estimation/parallel_map.py"], check=True, capture_output=True,
                            text=True).stdout
    # literal values, or expressions of earlier literal module constants (LOCAL_CONFIG holds dict(WORKER_ENV))
    names: dict = {}
    for node in ast.parse(source).body:
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name):
            try:
                names[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:
                if node.targets[0].id in SETTINGS:
                    names[node.targets[0].id] = eval(compile(ast.Expression(node.value), commit, "eval"),
                                                     {"__builtins__": {"dict": dict}}, dict(names))
    return {k: v for k, v in names.items() if k in SETTINGS}


def fleet_copy(fleet_yaml: Path, out: str) -> Path:
    """The same fleet writing to its own output folder."""
    raw = yaml.safe_load(fleet_yaml.read_text())
    raw["output"] = {"dir": out, "table": "fleet.parquet"}
    path = fleet_yaml.with_name(f"fleet_{out}.yaml")
    path.write_text(yaml.safe_dump(raw))
    return path


def skip_heap_freeze() -> None:
    """In a worker: mark its heap as frozen already, so parallel_map.freeze_heap is not run there."""
    from robocal.estimation import parallel_map as worker_side
    worker_side.FROZEN.append(True)


def calibrate_all(jobs) -> list[dict]:
    return [calibrate_unit(job) for job in jobs]


def spin(_, seconds=0.035):
    """An item of `seconds` of CPU in its thread."""
    start = time.thread_time()
    while time.thread_time() - start < seconds:
        pass
    return time.thread_time() - start


def cpu_seconds(me=None) -> float:
    """CPU time (user + system) of this process and all its children, live or ended: a way's difference of
    it is the CPU that all its processes used, whatever the load of other jobs on the machine did to its wall."""
    me = me or psutil.Process()
    t = me.cpu_times()
    total = t.user + t.system
    ended = resource.getrusage(resource.RUSAGE_CHILDREN)
    total += ended.ru_utime + ended.ru_stime
    for child in me.children(recursive=True):
        with contextlib.suppress(psutil.NoSuchProcess):
            c = child.cpu_times()
            total += c.user + c.system
    return total


def own_cpu() -> float:
    t = psutil.Process().cpu_times()
    return t.user + t.system


@contextlib.contextmanager
def settings(values: dict):
    """parallel_map's module settings set to `values` for the block."""
    old = {k: getattr(parallel_map, k) for k in SETTINGS}
    for k, v in values.items():
        setattr(parallel_map, k, v)
    try:
        yield
    finally:
        for k, v in old.items():
            setattr(parallel_map, k, v)


@contextlib.contextmanager
def started_cluster(values: dict, workers: int, jobs):
    """A LocalCluster with these settings, every worker warmed up with one real unit."""
    with settings(values), dask_client(workers=workers) as client:
        client.gather([client.submit(calibrate_all, jobs[k:k + 1], workers=[w], pure=False)
                       for k, w in enumerate(sorted(client.scheduler_info()["workers"]))])
        yield client


def pool_run(pool, jobs, workers: int) -> list[dict]:
    parts = [jobs[k::workers] for k in range(workers)]
    return [r for part in pool.map(calibrate_all, parts) for r in part]


def per_task_cpu(client) -> tuple[float, float]:
    """(CPU per task, CPU beside the items per 200 items at 30 a task), all processes, spinning 35 ms items."""
    spent = {}
    for b in (1, 30):
        with settings({}):
            real = parallel_map.batch_size
            parallel_map.batch_size = lambda *a, _b=b, **k: _b
            try:
                c0 = cpu_seconds()
                items = [r for _, r, _ in completed(client, spin, list(range(200)))]
                spent[b] = cpu_seconds() - c0 - sum(items)
            finally:
                parallel_map.batch_size = real
    return (spent[1] - spent[30]) / (200 - 7), spent[30]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--units", type=int, default=200)
    ap.add_argument("--samples", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--baseline", default="main", help="the commit whose Dask settings are the baseline")
    ap.add_argument("--started-only", action="store_true", help="leave out the ways from cold (more repeats in the "
                    "same time: the started ways are those the machine's load disturbs least)")
    ap.add_argument("--ways", default="", help="only the ways whose name contains one of these comma-separated "
                    "words (the plain processes always run: every ratio is to them)")
    args = ap.parse_args()
    W = args.workers
    base = settings_at(args.baseline)
    mine = {k: getattr(parallel_map, k) for k in SETTINGS}
    load = os.getloadavg()
    ctx = get_context("spawn")
    times: dict[str, list] = {}
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        fleet = simulated_fleet(tmp, args.units, samples=args.samples, seed=7)
        print(f"simulated {args.units} units of {args.samples} poses in {time.perf_counter() - t0:.1f} s "
              f"(os.cpu_count() = {os.cpu_count()}); baseline: {args.baseline}'s settings {base}\n")
        jobs = load_fleet(fleet.fleet_yaml).jobs
        os.environ.update(WORKER_ENV)          # the pool's processes as the cluster's workers
        with ctx.Pool(W) as pool:
            pool.map(calibrate_all, [jobs[k:k + 1] for k in range(W)])   # imports and first calls, before any clock

            def dask_cold(values, tag):
                def way(rep):
                    with settings(values):
                        return read_table(run_fleet(fleet_copy(fleet.fleet_yaml, f"{tag}{rep}"), workers=W).table_path)
                return way

            def pool_cold(rep):
                with ctx.Pool(W) as cold:
                    return pool_run(cold, load_fleet(fleet_copy(fleet.fleet_yaml, f"pc{rep}")).jobs, W)

            ways = {
                f"{W} plain processes (started)": lambda rep: pool_run(
                    pool, load_fleet(fleet_copy(fleet.fleet_yaml, f"p{rep}")).jobs, W),
                f"fleet run, {W} workers, {args.baseline}'s settings (started)": ("started", base, "b"),
                f"fleet run, {W} workers, this tree (started)": ("started", mine, "m"),
                f"fleet run, {W} workers, this tree, heap not frozen (started)": ("started", mine, "n"),
                f"fleet run, {W} workers, this tree, a second client (started)": ("started", mine, "a"),
                f"{W} plain processes (from cold)": pool_cold,
                f"fleet run --workers {W}, {args.baseline}'s settings (from cold)": dask_cold(base, "cb"),
                f"fleet run --workers {W}, this tree (from cold)": dask_cold(mine, "cm"),
            }
            wanted = [w for w in args.ways.split(",") if w]
            names = [n for n in ways if not (args.started_only and "cold" in n)
                     and (not wanted or "plain" in n or any(w in n for w in wanted))]
            for rep in range(args.repeats):
                for name in names[rep % len(names):] + names[:rep % len(names)]:
                    way = ways[name]
                    if isinstance(way, tuple):          # a started cluster: started and warmed before the clock
                        _, values, tag = way
                        with started_cluster(values, W, jobs) as client, settings(values):
                            if tag == "n":      # the workers skip parallel_map.freeze_heap
                                client.run(skip_heap_freeze)
                            t0, c0, o0 = time.perf_counter(), cpu_seconds(), own_cpu()
                            rows = read_table(run_fleet(fleet_copy(fleet.fleet_yaml, f"{tag}{rep}"),
                                                        scheduler=client.scheduler.address if tag == "a"
                                                        else client).table_path)
                            wall, cpu, own = time.perf_counter() - t0, cpu_seconds() - c0, own_cpu() - o0
                    else:
                        t0, c0, o0 = time.perf_counter(), cpu_seconds(), own_cpu()
                        rows = way(rep)
                        wall, cpu, own = time.perf_counter() - t0, cpu_seconds() - c0, own_cpu() - o0
                    times.setdefault(name, []).append((wall, sum(r["status"] == "converged" for r in rows),
                                                       statistics.mean(r["elapsed_s"] for r in rows), cpu, own))
        with started_cluster(mine, W, jobs) as client:
            task_cpu, beside = per_task_cpu(client)
    print(f"{'how':<62}{'converged':>10}{'wall s':>8}{'fit ms':>8}{'CPU s':>7}{'client CPU':>11}"
          f"{'vs plain: wall':>16}{'CPU':>6}{'wall, each repeat':>20}")
    med = {k: [statistics.median(x[i] for x in v) for i in range(5)] for k, v in times.items()}
    for name in names:
        wall, _, fit, cpu, own = med[name]
        ok = times[name][0][1]
        ref = times[f"{W} plain processes ({'from cold' if 'cold' in name else 'started'})"]
        each = sorted(p[0] / t[0] for p, t in zip(ref, times[name]))
        r_wall = statistics.median(each)
        r_cpu = statistics.median(p[3] / t[3] for p, t in zip(ref, times[name]))
        print(f"{name:<62}{ok:>10}{wall:>8.2f}{1e3 * fit:>8.1f}{cpu:>7.2f}{own:>11.2f}{100 * r_wall:>15.0f}%"
              f"{100 * r_cpu:>5.0f}%{100 * each[0]:>12.0f}-{100 * each[-1]:.0f}%")
    unit = med[f"{W} plain processes (started)"][2]
    print(f"\n{args.units} units; medians of {args.repeats} runs of each way (ways in turn, order rotated between "
          f"repeats); fit ms: one unit's calibrate_unit where it ran;\nvs plain: median over the repeats of the plain "
          f"processes' wall (CPU) time over this way's in the same repeat, like for like (started or from cold)\n"
          f"Dask's per-task cost (CPU of all processes, 200 spinning 35 ms items, 1 vs 30 a task, this tree's "
          f"settings): {1e3 * task_cpu:.1f} ms a task;\nCPU beside the items at 30 a task: {beside:.2f} s; "
          f"batch_size for {1e3 * unit:.0f} ms units: this tree {batch_size(unit, args.units, W)}, "
          f"{args.baseline} {batch_size(unit, args.units, W, base['TASK_OVERHEAD_S'], base['OVERHEAD_SHARE'])}\n"
          f"load average (1 min) before / after: {load[0]:.1f} / {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
