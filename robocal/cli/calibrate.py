"""`robocal calibrate CONFIG` and `robocal demo`: fit, print the summary, write the output folder
(robocal.workflows.calibrate.run_calibration)."""
from __future__ import annotations

import sys
from importlib.resources import files

from robocal.io.wording import plural
from robocal.workflows.calibrate import CalibrationRun, run_calibration
from robocal.workflows.setup import load_config


def progress(it):
    print(f"  iteration {it.iteration:3d}   cost {it.cost:12.6g}   step {it.step_norm:10.3g}   "
          f"damping {it.damping:9.3g}", file=sys.stderr, flush=True)


def brief(summary: str) -> str:
    """The summary up to the error table (status, refusals, errors per block and session), for --quiet."""
    head = summary.split("\nEstimated parameters", 1)[0].rstrip()
    return head + "\n(every parameter and the identifiability: summary.txt)" if head != summary.rstrip() else head


def print_run(run: CalibrationRun, quiet: bool, warnings: list[str] = ()) -> int:
    """The summary on stdout; warnings on stderr, and (not with --quiet) notes and the files written; the
    exit code: 0, or 3 for a fit that is refused or rejected."""
    result = run.result
    for warning in [*warnings, *run.warnings]:
        print(f"robocal: {warning}", file=sys.stderr)
    print(brief(result.summary(terminal=True)) if quiet else result.summary(terminal=True))
    if not quiet:
        for note in run.notes:
            print(f"robocal: {note}", file=sys.stderr)
        print("\nWrote " + ", ".join(str(f) for f in run.files.values()))
    if result.success and not run.rejected:
        return 0
    why = "rejected" if run.rejected and result.success else result.status
    print(f"\nrobocal: the fit is {why}; " + ("the calibrated URDF was written (--allow-failed)" if run.urdf_written
                                            else "no calibrated URDF written (--allow-failed writes it anyway)"),
          file=sys.stderr)
    return 3


def cmd_calibrate(args) -> int:
    setup = load_config(args.config)
    p = setup.problem
    if not args.quiet:
        print(f"robocal: {setup.robot.name}: {plural(len(p.values), 'sample')}, "
              f"{plural(sum(r.n_terms for r in p.residuals), 'measurement')} in {plural(len(p.residuals), 'block')}, "
              f"{plural(len(p.params.free_names), 'free parameter')}", file=sys.stderr)
    run = run_calibration(setup, args.output, force=args.force, allow_failed=args.allow_failed,
                          report=False if args.no_report else None, progress=None if args.quiet else progress)
    return print_run(run, args.quiet)


def cmd_demo(args) -> int:
    args.config = str(files("robocal.io") / "demo" / "ur5_calibrate.yaml")
    if not args.output:
        # the default folder is the demo's own: a re-run replaces it, but only while it holds nothing but what
        # robocal wrote there (the manifest rule of --force)
        args.output, args.force = "robocal-demo-output", True
    return cmd_calibrate(args)


def add_run_arguments(parser) -> None:
    """-o, --force, -q, --allow-failed (shared by calibrate, demo and select)."""
    parser.add_argument("-o", "--output", help="output folder (default: the config's output.dir)")
    parser.add_argument("--force", action="store_true",
                        help="replace an output folder robocal wrote (refused if it holds other files)")
    parser.add_argument("-q", "--quiet", action="store_true", help="print only errors and the summary")
    parser.add_argument("--allow-failed", action="store_true",
                        help="go on despite implausible data and write the URDF even if the fit failed")


def add_parser(subparsers) -> None:
    c = subparsers.add_parser("calibrate", help="fit a robot model to measurements described by a YAML config")
    c.add_argument("config", help="calibration YAML (docs/config.md)")
    d = subparsers.add_parser("demo", help="calibrate a simulated UR5 from built-in data")
    for p in (c, d):
        add_run_arguments(p)
        p.add_argument("--no-report", action="store_true", help="do not write report.html")
    c.set_defaults(handler=cmd_calibrate)
    d.set_defaults(handler=cmd_demo)
