"""`robocal calibrate CONFIG` and `robocal demo`: fit, print the summary, write the output folder."""
from __future__ import annotations

import json
import sys
from importlib.resources import files
from pathlib import Path

from robocal.errors import RobocalError
from robocal.estimation.calibrate import calibrate
from robocal.estimation.iso9283_run import iso9283_from_config
from robocal.io.config import load_config
from robocal.io.output import write_results
from robocal.viz.scene import scene_bytes


def _progress(it):
    print(f"  iteration {it.iteration:3d}   cost {it.cost:12.6g}   step {it.step_norm:10.3g}   "
          f"damping {it.damping:9.3g}", file=sys.stderr, flush=True)


def cmd_calibrate(args) -> int:
    setup = load_config(args.config)
    out = Path(args.output).resolve() if args.output else setup.output_dir
    if out.exists() and not args.force:
        raise RobocalError(f"{out}: output folder exists; pass --force to replace it")
    p = setup.problem
    print(f"robocal: {setup.robot.name}: {len(p.values)} samples, {sum(r.n_terms for r in p.residuals)} "
          f"measurements in {len(p.residuals)} blocks, {len(p.params.free_names)} free parameters", file=sys.stderr)
    before = p.params.copy()      # the scene shows the model before and after the fit
    result = calibrate(p, setup.options, progress=None if args.quiet else _progress,
                       source=", ".join(str(t.path) for t in setup.tables.values()))
    extra = {"scene.json": scene_bytes(setup, result, before)}
    iso = _iso9283(args.config, result) if "iso9283" in (setup.raw or {}) else None
    if iso is not None:
        extra["iso9283.json"] = (json.dumps(iso, indent=2) + "\n").encode()
    if not args.no_report and (setup.raw.get("output") or {}).get("report", True):
        try:
            from robocal.viz.report import report_bytes   # matplotlib and meshcat: the optional [viz] extra
            extra["report.html"] = report_bytes(result, extra["scene.json"], meshes=False,  # 1.5 MB, not 10
                                                iso9283=iso)
        except ImportError as exc:   # matplotlib / meshcat come with the [viz] extra
            print(f"robocal: no report.html ({exc.name} is not installed: pip install 'robocal[viz]')",
                  file=sys.stderr)
    files = write_results(setup.robot, result, out, force=args.force, allow_failed=args.allow_failed, extra=extra)
    print(result.summary())
    print("\nWrote " + ", ".join(str(f) for f in files.values()))
    if not result.success:
        print(f"\nrobocal: the fit is {result.status}; no calibrated URDF written "
              f"(--allow-failed writes it anyway)" if "urdf" not in files else "", file=sys.stderr)
        return 3
    return 0


def _iso9283(config, result) -> dict:
    """ISO 9283 figures of the config's `iso9283:` rows with the parameters just fitted."""
    import tempfile   # noqa: (removed below when calibrate builds its setup once)

    with tempfile.TemporaryDirectory() as tmp:
        fitted = Path(tmp) / "result.json"
        fitted.write_text(result.to_json())
        return iso9283_from_config(config, parameters=fitted).to_dict()


def cmd_demo(args) -> int:
    demo = files("robocal.io") / "demo" / "ur5_calibrate.yaml"
    args.config = str(demo)
    args.output = args.output or "robocal-demo-output"
    return cmd_calibrate(args)


def add_parser(subparsers) -> None:
    c = subparsers.add_parser("calibrate", help="fit a robot model to measurements described by a YAML config")
    c.add_argument("config", help="calibration YAML (docs/config.md)")
    c.add_argument("-o", "--output", help="output folder (default: the config's output.dir)")
    c.set_defaults(handler=cmd_calibrate)
    d = subparsers.add_parser("demo", help="calibrate a simulated UR5 from built-in data")
    d.add_argument("-o", "--output", help="output folder (default: ./robocal-demo-output)")
    d.set_defaults(handler=cmd_demo)
    for p in (c, d):
        p.add_argument("--force", action="store_true", help="replace an output folder robocal wrote")
        p.add_argument("-q", "--quiet", action="store_true", help="no progress display")
        p.add_argument("--allow-failed", action="store_true", help="write the URDF even if the fit failed")
        p.add_argument("--no-report", action="store_true", help="do not write report.html")
