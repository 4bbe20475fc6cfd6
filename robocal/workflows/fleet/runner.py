"""`fleet run`: calibrate every unit of a fleet.yaml on Dask, streaming rows to the table.

Units whose inputs and config hashes already have a final row are skipped (a re-run after a crash
or a killed worker does only what is left). Every other unit is submitted at once; each finished
unit's row is put into the table, which is rewritten atomically every FLUSH_SECONDS, or less often once a
rewrite takes long (`flush_interval`), and at the end (also on an interrupt), so a crash loses at most the
last interval's units, which a re-run redoes.
A worker that dies takes its running task with it: Dask runs that task again on another worker, and
only a task that kills its workers repeatedly comes back as a 'lost' row.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from robocal.estimation.parallel_map import completed, dask_client
from robocal.workflows.fleet.manifest import FleetSpec, UnitJob, load_fleet
from robocal.workflows.fleet.table import FleetTable
from robocal.workflows.fleet.unit import FINAL_STATUSES, LOST, calibrate_unit

log = logging.getLogger(__name__)
#: the table is rewritten at most this often (s) while units finish, and once at the end
FLUSH_SECONDS = 1.0
#: the rewrites may take at most this share of the run's time: each one rewrites the whole table (Parquet, 8 ms
#: at 200 rows, 0.3 s at 10000, this machine), and the client's process shares the cores with the workers
WRITE_SHARE = 0.02


def flush_interval(write_seconds: float) -> float:
    """Seconds until the next rewrite after one that took write_seconds: FLUSH_SECONDS, or longer so that rewrites
    take at most WRITE_SHARE of the time (10000 rows: one every 15 s instead of every second)."""
    return max(FLUSH_SECONDS, write_seconds / WRITE_SHARE)


@dataclass
class FleetRun:
    """What one `fleet run` did."""

    table_path: Path
    units: int
    skipped: int
    calibrated: int = 0
    statuses: dict[str, int] = field(default_factory=dict)
    failures: list[dict] = field(default_factory=list)    # rows whose status is not 'converged'


def lost_row(job: UnitJob, exc: BaseException) -> dict:
    return {**job.identity(), "status": LOST,
            "message": f"the cluster lost this unit's task ({type(exc).__name__}: {exc}); a re-run calibrates it"}


def run_fleet(fleet: str | Path | FleetSpec, scheduler=None, workers: int | None = None,
              progress: Callable[[int, int, dict], None] | None = None) -> FleetRun:
    """Calibrate the units of `fleet` not yet in its table; progress(done, to_do, row) after each one.
    scheduler: a Dask scheduler's address or a running dask.distributed Client (used as it is, left open);
    neither: a LocalCluster of `workers` processes (robocal.estimation.parallel_map.dask_client)."""
    spec = fleet if isinstance(fleet, FleetSpec) else load_fleet(fleet)
    table = FleetTable.open(spec.table_path)
    todo = [j for j in spec.jobs if not table.is_done(j, FINAL_STATUSES)]
    run = FleetRun(spec.table_path, len(spec.jobs), len(spec.jobs) - len(todo))
    log.info("%d units, %d already in %s, %d to calibrate", run.units, run.skipped, spec.table_path, len(todo))
    if not todo:
        return run
    last_write, interval = time.monotonic(), FLUSH_SECONDS
    with dask_client(scheduler, workers) as client:
        try:
            for i, row, exc in completed(client, calibrate_unit, todo):
                row = lost_row(todo[i], exc) if exc is not None else row
                table.put(row)
                if time.monotonic() - last_write >= interval:
                    started = time.monotonic()
                    table.write()
                    last_write = time.monotonic()
                    interval = flush_interval(last_write - started)
                run.calibrated += 1
                run.statuses[row["status"]] = run.statuses.get(row["status"], 0) + 1
                if row["status"] != "converged":
                    run.failures.append(row)
                if progress:
                    progress(run.calibrated, len(todo), row)
        finally:   # also on an interrupt: every unit finished so far is kept
            table.write()
    return run
