"""`robocal select CONFIG`: fit a ladder of models, choose by cross-validation, write the chosen one's result
as `robocal calibrate` would (docs/validation.md)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from robocal.cli.cv import add_fold_arguments
from robocal.estimation.calibrate import calibrate
from robocal.workflows.evaluate import portable_config, setup_for_data
from robocal.workflows.select import select_model
from robocal.io.output_folder import check_replaceable
from robocal.workflows.outputs import write_results
from robocal.viz.scene import scene_bytes, scene_note

def cmd_select(args) -> int:
    selection = select_model(args.config, args.folds, args.loo, args.group)
    for line in selection.table():
        print(line)
    rung = selection.rungs[selection.chosen]
    setup = setup_for_data(args.config, parameters=rung.parameters)
    out = Path(args.output).resolve() if args.output else setup.output_dir
    check_replaceable(out, args.force)     # before the fit, not only after it
    nominal = setup.problem.params.copy()
    result = calibrate(setup.problem, setup.options, source=str(args.config))
    before = result.registered_nominal(nominal)   # the scene shows the model before and after the fit
    note = scene_note(setup)
    if note:
        print(f"robocal: {note}", file=sys.stderr)
    extra = {"selection.json": (json.dumps(selection.to_dict(), indent=2, allow_nan=True) + "\n").encode(),
             "config.yaml": portable_config(args.config, rung.parameters),
             "scene.json": scene_bytes(setup, result, before)}
    if (setup.raw.get("output") or {}).get("report", True):
        try:
            from robocal.viz.report import report_bytes   # matplotlib and meshcat: the optional [viz] extra
            extra["report.html"] = report_bytes(result, extra["scene.json"], meshes=False)
        except ImportError as exc:
            print(f"robocal: no report.html ({exc.name} is not installed: pip install 'robocal[viz]')",
                  file=sys.stderr)
    files = write_results(setup.robot, result, out, force=args.force, allow_failed=args.allow_failed, extra=extra)
    print(f"\nChosen: {rung.name}, fitted on all samples:\n")
    print(result.summary())
    print("\nWrote " + ", ".join(str(f) for f in files.values()))
    if not result.success:
        print(f"\nrobocal: the chosen model's fit is {result.status}; no calibrated URDF written", file=sys.stderr)
        return 3
    return 0

def add_parser(subparsers) -> None:
    s = subparsers.add_parser("select", help="choose a model by cross-validation (ladder + one-standard-error rule)")
    s.add_argument("config", help="calibration YAML; compliance / backlash / tilt it asks for extend the ladder")
    add_fold_arguments(s)
    s.add_argument("-o", "--output", help="output folder (default: the config's output.dir)")
    s.add_argument("--force", action="store_true", help="replace an output folder robocal wrote")
    s.add_argument("--allow-failed", action="store_true", help="write the URDF even if the fit failed")
    s.set_defaults(handler=cmd_select)
