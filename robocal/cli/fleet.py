"""`robocal fleet run FLEET.yaml` and `robocal fleet report TABLE`: the command line of
robocal.workflows.fleet (parsing and printing only). See docs/fleet.md."""
from __future__ import annotations

import logging
import sys
from pathlib import Path

from robocal.workflows.fleet.report import DEFAULT_THRESHOLD, fleet_report, summary_lines
from robocal.io.text_files import write_atomic


def _progress(done: int, total: int, row: dict) -> None:
    width = 30
    bar = "#" * (width * done // total)
    print(f"\r  [{bar:<{width}}] {done}/{total}  {row['key']}: {row['status']:<14}", end="" if done < total else "\n",
          file=sys.stderr, flush=True)


def cmd_run(args) -> int:
    import distributed   # optional [fleet] extra; imported here first so that its INFO chatter can be quieted
    from robocal.workflows.fleet.runner import run_fleet   # dask and pyarrow: the optional [fleet] extra

    if not args.verbose:
        logging.getLogger(distributed.__name__).setLevel(logging.WARNING)

    where = f"scheduler {args.scheduler}" if args.scheduler else f"a local cluster of {args.workers or 'all'} workers"
    if not args.quiet:
        print(f"robocal fleet: {args.fleet} on {where}", file=sys.stderr)
    run = run_fleet(args.fleet, scheduler=args.scheduler, workers=args.workers,
                    progress=None if args.quiet else _progress)
    print(f"{run.units} units: {run.skipped} already in the table, {run.calibrated} calibrated"
          + ("" if not run.statuses else " (" + ", ".join(f"{n} {s}" for s, n in sorted(run.statuses.items())) + ")"))
    for r in run.failures:
        print(f"  {r['key']}: {r['status']}: {r.get('message') or ''}")
    if not args.quiet:
        print(f"Wrote {run.table_path}")
    return 3 if run.failures else 0


def cmd_report(args) -> int:
    from robocal.workflows.fleet.table import read_table   # pyarrow: the optional [fleet] extra

    rep = fleet_report(read_table(args.table), threshold=args.threshold)
    print("\n".join(summary_lines(rep)))
    out = Path(args.output) if args.output else Path(args.table).with_suffix(".html")
    try:
        from robocal.workflows.fleet.page import fleet_page   # matplotlib: the optional [viz] extra
    except ImportError as exc:
        print(f"robocal: no HTML page ({exc.name} is not installed: pip install 'robocal[viz]')", file=sys.stderr)
        return 0
    write_atomic(out, fleet_page(rep).encode("utf-8"))
    if not args.quiet:
        print(f"\nWrote {out}")
    return 0


def add_parser(subparsers) -> None:
    f = subparsers.add_parser("fleet", help="calibrate many units on Dask into one table; compare them")
    sub = f.add_subparsers(dest="fleet_command", required=True, help="run: calibrate every unit; report: the fleet page")
    r = sub.add_parser("run", help="calibrate every unit of a fleet.yaml not yet in its table")
    r.add_argument("fleet", help="fleet YAML: template config + manifest of units (docs/fleet.md)")
    r.add_argument("--workers", type=int, default=None, help="local cluster size (default: the usable cores)")
    r.add_argument("--scheduler", default=None, help="address of a running Dask scheduler (tcp://host:8786)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.set_defaults(handler=cmd_run)
    p = sub.add_parser("report", help="distribution, outliers and drift of a fleet table; HTML page")
    p.add_argument("table", help="fleet table (Parquet) written by `robocal fleet run`")
    p.add_argument("-o", "--output", help="HTML page (default: the table's name with .html)")
    p.add_argument("--threshold", type=float, default=DEFAULT_THRESHOLD,
                   help=f"outlier and drift threshold in robust standard deviations (default {DEFAULT_THRESHOLD:g})")
    p.set_defaults(handler=cmd_report)
