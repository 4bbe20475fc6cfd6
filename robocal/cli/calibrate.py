"""`robocal calibrate CONFIG` and `robocal demo`: fit, print the summary, write the output folder."""
from __future__ import annotations

import json
import sys
from importlib.resources import files
from pathlib import Path

from robocal.estimation.calibrate import calibrate
from robocal.workflows.iso9283 import iso9283_run, iso9283_section
from robocal.workflows.config import load_config
from robocal.workflows.data_check import nominal_states, units_findings
from robocal.io.output_folder import check_replaceable
from robocal.workflows.outputs import write_results
from robocal.viz.scene import scene_bytes, scene_note
from robocal.io.wording import plural


def _progress(it):
    print(f"  iteration {it.iteration:3d}   cost {it.cost:12.6g}   step {it.step_norm:10.3g}   "
          f"damping {it.damping:9.3g}", file=sys.stderr, flush=True)


def check_data(setup, allow_failed: bool) -> None:
    """Refuse implausible data before any fit (a units mix-up); with --allow-failed only warn."""
    findings = units_findings(setup, nominal_states(setup))
    if findings and not allow_failed:
        raise findings[0]
    for f in findings:
        print(f"robocal: warning: {f} (going on: --allow-failed)", file=sys.stderr)


def cmd_calibrate(args) -> int:
    setup = load_config(args.config)
    out = Path(args.output).resolve() if args.output else setup.output_dir
    check_replaceable(out, args.force)
    if "iso9283" in setup.raw:
        iso9283_section(setup)            # a mistake there costs no fitting time
    check_data(setup, args.allow_failed)
    p = setup.problem
    if not args.quiet:
        print(f"robocal: {setup.robot.name}: {plural(len(p.values), 'sample')}, "
              f"{plural(sum(r.n_terms for r in p.residuals), 'measurement')} in {plural(len(p.residuals), 'block')}, "
              f"{plural(len(p.params.free_names), 'free parameter')}", file=sys.stderr)
    nominal = p.params.copy()
    result = calibrate(p, setup.options, progress=None if args.quiet else _progress,
                       source=", ".join(str(t.path) for t in setup.tables.values()))
    # the scene's "before" is the model the "before" figures describe: the nominal robot, registered
    note = scene_note(setup)
    if note and not args.quiet:
        print(f"robocal: {note}", file=sys.stderr)
    extra = {"scene.json": scene_bytes(setup, result, result.registered_nominal(nominal))}
    iso = None
    if "iso9283" in setup.raw:
        iso = iso9283_run(setup, nominal, p.params, result).to_dict()
        extra["iso9283.json"] = (json.dumps(iso, indent=2) + "\n").encode()
    if not args.no_report and (setup.raw.get("output") or {}).get("report", True):
        try:
            from robocal.viz.report import report_bytes   # matplotlib and meshcat: the optional [viz] extra
            extra["report.html"] = report_bytes(result, extra["scene.json"], meshes=False,  # 1.5 MB, not 10
                                                iso9283=iso)
        except ImportError as exc:   # matplotlib / meshcat come with the [viz] extra
            if not args.quiet:
                print(f"robocal: no report.html ({exc.name} is not installed: pip install 'robocal[viz]')",
                      file=sys.stderr)
    written = write_results(setup.robot, result, out, force=args.force, allow_failed=args.allow_failed,
                            extra=extra)
    print(result.summary())
    if not args.quiet:
        print("\nWrote " + ", ".join(str(f) for f in written.values()))
    if not result.success:
        print(f"\nrobocal: the fit is {result.status}; no calibrated URDF written "
              f"(--allow-failed writes it anyway)" if not any(n.endswith(".urdf") for n in written) else
              f"\nrobocal: the fit is {result.status}; the calibrated URDF was written (--allow-failed)",
              file=sys.stderr)
        return 3
    return 0


def cmd_demo(args) -> int:
    demo = files("robocal.io") / "demo" / "ur5_calibrate.yaml"
    args.config = str(demo)
    if not args.output:
        # the default folder is the demo's own: a re-run replaces it, but only while it holds nothing but what
        # robocal wrote there (the manifest rule of --force)
        args.output, args.force = "robocal-demo-output", True
    return cmd_calibrate(args)


def add_parser(subparsers) -> None:
    c = subparsers.add_parser("calibrate", help="fit a robot model to measurements described by a YAML config")
    c.add_argument("config", help="calibration YAML (docs/config.md)")
    c.add_argument("-o", "--output", help="output folder (default: the config's output.dir)")
    c.set_defaults(handler=cmd_calibrate)
    d = subparsers.add_parser("demo", help="calibrate a simulated UR5 from built-in data")
    d.add_argument("-o", "--output", help="output folder (default: ./robocal-demo-output, replaced by a re-run "
                                          "while it holds only what robocal wrote)")
    d.set_defaults(handler=cmd_demo)
    for p in (c, d):
        p.add_argument("--force", action="store_true",
                       help="replace an output folder robocal wrote (refused if it holds other files)")
        p.add_argument("-q", "--quiet", action="store_true", help="print only errors and the summary")
        p.add_argument("--allow-failed", action="store_true",
                       help="go on despite implausible data and write the URDF even if the fit failed")
        p.add_argument("--no-report", action="store_true", help="do not write report.html")
