"""`robocal evaluate RESULT_DIR DATA.csv [--detections FILE]`: score a calibrated model on another session
(docs/validation.md; a camera block's new images: docs/camera.md);
`robocal evaluate IDENTIFY_DIR LOG.yaml`: predict a new log's torques with an identified dynamic model
(robocal.cli.identify.evaluate_dynamics; docs/dynamics_tiago.md)."""
from __future__ import annotations

import sys
from pathlib import Path

from robocal.cli.identify import evaluate_dynamics
from robocal.errors import InputError
from robocal.workflows.evaluate import evaluate_result, write_evaluation


def cmd_evaluate(args) -> int:
    folder = Path(args.result_dir).resolve()
    if (folder / "dynamics.yaml").is_file():           # a `robocal identify` folder: its own evaluation
        return evaluate_dynamics(folder, Path(args.data), args.quiet)
    config = Path(args.config) if args.config else folder / "config.yaml"
    if not config.is_file():
        raise InputError("no config.yaml in the result folder: pass --config CALIB.yaml (the config it was "
                         "fitted with)", source=str(config), field="--config")
    report = evaluate_result(folder, Path(args.data).resolve(), config, args.refit,
                             detections=detection_files(args.detections))
    if not args.quiet:
        print(f"Evaluation of {folder} on {report.data}")
    print("Refitted on this session: " + (", ".join(report.refitted) or "nothing (--refit PATTERN re-registers "
                                                                      "a frame per session, e.g. 'base.*')"))
    print("RMS and max of the error norm (3D per point / orientation; 2D per image corner), samples inside / "
          "outside the training joint ranges:")
    print(f"  {'block':<20}{'error':<22}{'samples':<10}{'n':>5}{'RMS |e|':>12}{'max |e|':>12}")
    for b in report.blocks:
        for part in ("all", "inside_training_range", "outside_training_range"):
            st = b[part]
            if st["n"]:
                print(f"  {b['name']:<20}{b['norm_of']:<22}{part.split('_')[0]:<10}{st['n']:>5}"
                      f"{st['rms_norm']:>9.4g} {b['unit']:<2}{st['max_norm']:>9.4g} {b['unit']}")
        for label, st in (b.get("points") or {}).items():
            print(f"  {b['name'] + ' ' + label:<20}{'3D position error':<22}{'all':<10}{st['n']:>5}"
                  f"{st['rms_norm']:>9.4g} {b['unit']:<2}{st['max_norm']:>9.4g} {b['unit']}")
        images = b.get("images") or {}
        if images and not args.quiet:   # one line an image
            for label, st in images.items():
                print(f"  {b['name'] + ' ' + label:<20}{'image':<22}{'':<10}{st['n']:>5}"
                      f"{st['rms_norm']:>9.4g} {b['unit']:<2}{st['max_norm']:>9.4g} {b['unit']}")
    for o in report.outside:
        beyond = ", ".join(f"{j} {v:+.3g}" for j, v in o["beyond_range"].items())
        print(f"  outside the training range: CSV line {o['csv_line']} ({beyond}, SI)")
    path, note = write_evaluation(folder, report)
    if not args.quiet:
        if note:
            print(f"robocal: {note}", file=sys.stderr)
        print(f"\nWrote {path}")
    return 0


def detection_files(values: list[str]) -> dict[str | None, Path]:
    """--detections FILE (the config's one camera block) or NAME=FILE, each once."""
    out = {}
    for v in values:
        name, _, path = v.rpartition("=") if "=" in v and not Path(v).exists() else ("", "", v)
        key = name or None
        if key in out:
            raise InputError(f"{'camera block ' + repr(name) if name else 'the camera block'} given two detections "
                             "files", field="--detections")
        if not Path(path).is_file():
            raise InputError(f"detections file not found: {path}", source=path, field="--detections")
        out[key] = Path(path).resolve()
    return out


def add_parser(subparsers) -> None:
    e = subparsers.add_parser("evaluate", help="score a calibrated model (output folder) on another session, or "
                                               "predict a new log's torques with an identified dynamic model")
    e.add_argument("result_dir", help="output folder of robocal calibrate / select / identify")
    e.add_argument("data", help="CSV with the config's columns (another session); for an identify folder, a "
                                "LOG.yaml describing the new log")
    e.add_argument("--config", help="the calibration YAML (default: RESULT_DIR/config.yaml)")
    e.add_argument("--refit", action="append", default=[], metavar="PATTERN",
                   help="parameters re-registered per session, refitted on this data (e.g. 'base.*'); repeatable")
    e.add_argument("--detections", action="append", default=[], metavar="[NAME=]FILE",
                   help="a camera block's detections of the new images (sample, corner, u, v); NAME= when the "
                        "config has several camera blocks")
    e.set_defaults(handler=cmd_evaluate)
