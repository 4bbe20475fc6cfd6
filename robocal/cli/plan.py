"""`robocal plan CONFIG`: the command line of robocal.workflows.plan (parsing and printing only)."""
from __future__ import annotations

import sys

from robocal.workflows.plan import plan_from_config, summary, write_plan
from robocal.io.output_folder import check_replaceable


def cmd_plan(args) -> int:
    if args.output:
        check_replaceable(args.output, args.force)     # before the work, not only after it
    plan = plan_from_config(args.config, seed=args.seed, scheduler=args.scheduler, workers=args.workers)
    files = write_plan(plan, args.output, force=args.force)
    print(summary(plan))
    if not args.quiet:
        print("\nWrote " + ", ".join(str(f) for f in files.values()))
    if not plan.selection.identifiability.ok:
        print("\nrobocal: the chosen poses leave parameters undetermined; increase plan.N or widen the "
              "candidates", file=sys.stderr)
        return 3
    return 0


def add_parser(subparsers):
    p = subparsers.add_parser("plan", help="choose poses to measure and predict the calibration's accuracy")
    p.add_argument("config", help="calibration YAML with a plan: section (docs/experiment_design.md); the data "
                                  "file need not exist")
    p.add_argument("-o", "--output", help="output folder (default: the config's plan.output.dir)")
    p.add_argument("--seed", type=int, default=None, help="override plan.seed")
    p.add_argument("--force", action="store_true",
                   help="replace an output folder robocal wrote (refused if it holds other files)")
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors and the summary")
    p.add_argument("--workers", type=int, default=None, help="compute the accuracy curve on a local Dask cluster "
                   "of this many workers (the [fleet] extra; docs/fleet.md)")
    p.add_argument("--scheduler", default=None, help="compute the accuracy curve on this Dask scheduler")
    p.set_defaults(handler=cmd_plan)
    return p
