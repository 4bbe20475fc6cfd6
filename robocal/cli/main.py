"""The `robocal` command. The only module that writes to the terminal."""
from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

import numpy as np

from robocal.errors import RobocalError


def _progress(it):
    print(f"  iteration {it.iteration:3d}   cost {it.cost:12.6g}   step {it.step_norm:10.3g}   "
          f"damping {it.damping:9.3g}", file=sys.stderr, flush=True)


def cmd_calibrate(args) -> int:
    from robocal.estimation.calibrate import calibrate
    from robocal.io.config import load_config
    from robocal.io.output import write_results
    from robocal.viz.scene import scene_bytes

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
            from robocal.viz.report import report_bytes
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
    import tempfile

    from robocal.cli.iso9283 import iso9283_from_config

    with tempfile.TemporaryDirectory() as tmp:
        fitted = Path(tmp) / "result.json"
        fitted.write_text(result.to_json())
        return iso9283_from_config(config, parameters=fitted).to_dict()


def cmd_simulate(args) -> int:
    from robocal.design.dataset import simulate_dataset

    written = simulate_dataset(args.config, args.output, seed=args.seed, force=args.force)
    print("Wrote " + ", ".join(str(p) for p in written))
    return 0


def cmd_demo(args) -> int:
    from importlib.resources import files

    demo = files("robocal.io") / "demo" / "ur5_calibrate.yaml"
    args.config = str(demo)
    args.output = args.output or "robocal-demo-output"
    return cmd_calibrate(args)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="robocal", description="Calibrate robot models from measurements.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log library messages")
    sub = parser.add_subparsers(dest="command", required=True)
    c = sub.add_parser("calibrate", help="fit a robot model to measurements described by a YAML config")
    c.add_argument("config")
    c.add_argument("-o", "--output", help="output folder (default: the config's output.dir)")
    s = sub.add_parser("simulate", help="write a synthetic dataset (and its truth) from a YAML config")
    s.add_argument("config")
    s.add_argument("-o", "--output", help="CSV to write (default: the config's data.csv)")
    s.add_argument("--seed", type=int, default=None)
    d = sub.add_parser("demo", help="calibrate a simulated UR5 from built-in data")
    d.add_argument("-o", "--output", help="output folder (default: ./robocal-demo-output)")
    for p in (c, s, d):
        p.add_argument("--force", action="store_true", help="replace existing output")
    from robocal.cli.iso9283 import add_parser as add_iso9283_parser, cmd_iso9283
    add_iso9283_parser(sub)
    from robocal.cli.plan import add_parser as add_plan_parser, cmd_plan
    add_plan_parser(sub)
    from robocal.cli.view import add_parsers as add_view_parsers, cmd_report, cmd_view
    add_view_parsers(sub)
    for p in (c, d):
        p.add_argument("-q", "--quiet", action="store_true", help="no progress display")
        p.add_argument("--allow-failed", action="store_true", help="write the URDF even if the fit failed")
        p.add_argument("--no-report", action="store_true", help="do not write report.html")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(name)s: %(message)s")
    np.set_printoptions(precision=6, suppress=True)
    handler = {"calibrate": cmd_calibrate, "simulate": cmd_simulate, "demo": cmd_demo,
               "iso9283": cmd_iso9283, "plan": cmd_plan, "view": cmd_view, "report": cmd_report}[args.command]
    try:
        return handler(args)
    except RobocalError as exc:
        print(f"robocal: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
