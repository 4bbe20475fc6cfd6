"""Benchmark: a fleet of 200 simulated UR5 units (30 tracker poses each) calibrated on Dask with 1
and 2 worker processes, against the same fits one by one in this process (the baseline, same run).

    OMP_NUM_THREADS=1 python benchmarks/fleet.py [--units 200] [--samples 30]

Each line times a fresh output folder (nothing resumed). Fleet runs include starting the
LocalCluster (measured alone on the last line). A control splits the units over 2 plain processes
(multiprocessing, started before the clock): the scaling the machine itself allows. Paste the table
into docs/fleet.md.
"""
import argparse
import os
import tempfile
import time
from multiprocessing import get_context
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import yaml  # noqa: E402

from robocal.estimation.parallel_map import dask_client  # noqa: E402
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


def keep(best: dict, how: str, wall: float, done: list[dict]) -> None:
    """Keep the fastest run of each way: (how, wall s, converged units, mean fit s per unit)."""
    if how not in best or wall < best[how][1]:
        best[how] = (how, wall, sum(r["status"] == "converged" for r in done),
                     sum(r["elapsed_s"] for r in done) / len(done))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--units", type=int, default=200)
    ap.add_argument("--samples", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=2, help="best of this many runs of each way")
    args = ap.parse_args()
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        fleet = simulated_fleet(tmp, args.units, samples=args.samples, seed=7)
        print(f"simulated {args.units} units of {args.samples} poses in {time.perf_counter() - t0:.1f} s "
              f"(os.cpu_count() = {os.cpu_count()})\n")
        # Best of `repeats` for each way, interleaved, so that a burst of load from other processes on
        # the machine does not decide the comparison; every repeat writes a fresh output folder.
        best = {}
        for rep in range(args.repeats):
            spec = load_fleet(fleet_copy(fleet.fleet_yaml, f"serial{rep}"))
            t0 = time.perf_counter()
            done = [calibrate_unit(job) for job in spec.jobs]
            keep(best, "one by one, this process", time.perf_counter() - t0, done)
            # control: the same split over 2 plain processes (no Dask), the scaling this machine allows
            halves = [spec.jobs[0::2], spec.jobs[1::2]]
            with get_context("spawn").Pool(2) as pool:
                pool.map(calibrate_all, [h[:2] for h in halves])     # start-up and imports not timed
                t0 = time.perf_counter()
                done = [r for part in pool.map(calibrate_all, halves) for r in part]
            keep(best, "2 plain processes, no Dask", time.perf_counter() - t0, done)
            for workers in (1, 2):
                t0 = time.perf_counter()
                run = run_fleet(fleet_copy(fleet.fleet_yaml, f"w{workers}_{rep}"), workers=workers)
                keep(best, f"fleet run, {workers} worker{'s' * (workers > 1)}", time.perf_counter() - t0,
                     read_table(run.table_path))
        rows = list(best.values())
        serial = rows[0][1]
        t0 = time.perf_counter()
        with dask_client(workers=2):
            pass
        start = time.perf_counter() - t0
    print(f"{'how':<28}{'units':>6}{'converged':>11}{'wall s':>9}{'wall ms / unit':>16}{'fit ms / unit':>15}"
          f"{'vs one by one':>15}")
    for how, wall, ok, fit in rows:
        print(f"{how:<28}{args.units:>6}{ok:>11}{wall:>9.2f}{1e3 * wall / args.units:>16.1f}{1e3 * fit:>15.1f}"
              f"{serial / wall:>14.2f}x")
    print(f"{'start + stop a 2-worker LocalCluster':<54}{start:>9.2f}")
    print(f"\nbest of {args.repeats} runs of each way; fit ms / unit: one unit's calibrate_unit (set-up, fit, "
          f"output folder)\nas timed where it ran; load average (1 min) before / after: {load[0]:.1f} / {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
