"""`robocal iso9283 CONFIG`: the command line of robocal.workflows.iso9283 (parsing and printing only)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from robocal.errors import InputError
from robocal.estimation.iso9283 import summary
from robocal.workflows.input_checks import check_inputs
from robocal.workflows.iso9283 import check_iso9283, iso9283_from_setup
from robocal.workflows.setup import load_config
from robocal.io.text_files import write_atomic


def add_parser(subparsers):
    p = subparsers.add_parser("iso9283", help="ISO 9283 accuracy and repeatability, nominal and calibrated")
    p.add_argument("config", help="calibration YAML with an iso9283 section")
    p.add_argument("-o", "--output", help="write the figures as JSON (SI units) to this file")
    p.add_argument("--parameters", help="calibrated parameters from a previous result.json (no fit)")
    p.add_argument("--force", action="store_true", help="replace an existing output file")
    p.add_argument("--allow-failed", action="store_true", help="go on despite implausible data (a units mix-up)")
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors and the figures")
    p.set_defaults(handler=cmd_iso9283)
    return p


def cmd_iso9283(args) -> int:
    """Print the figures (mm, mrad); write JSON with -o. The CLI owns the terminal."""
    out = Path(args.output).resolve() if args.output else None
    if out is not None and out.exists() and not args.force:
        raise InputError("file exists; pass --force to replace it", source=str(out))
    setup = load_config(args.config)
    check_iso9283(setup)
    for note in check_inputs(setup, args.allow_failed):
        print(f"robocal: {note}", file=sys.stderr)
    run = iso9283_from_setup(setup, args.parameters)
    if run.result is not None and not run.result.success:
        print(f"robocal: the calibration is {run.result.status}; calibrated figures are unreliable",
              file=sys.stderr)
    print(f"frame: {run.frame}")
    print(summary([run.nominal, run.calibrated]))
    if out is not None:
        write_atomic(out, (json.dumps(run.to_dict(), indent=2) + "\n").encode())
        if not args.quiet:
            print(f"\nWrote {out}")
    return 0
