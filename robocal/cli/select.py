"""`robocal select CONFIG`: fit a ladder of models, choose by cross-validation, write the chosen one's result
as `robocal calibrate` would (robocal.workflows.select; docs/validation.md)."""
from __future__ import annotations

from robocal.cli.calibrate import add_run_arguments, print_run
from robocal.cli.cv import add_fold_arguments
from robocal.io.output_folder import check_replaceable
from robocal.workflows.select import run_selected, select_model
from robocal.workflows.config_read import read_config


def cmd_select(args) -> int:
    config = read_config(args.config)                   # once, for the ladder and the chosen fit
    check_replaceable(args.output or config.output.dir, args.force)   # before the ladder's fits, not after them
    selection = select_model(config, args.folds, args.loo, args.group, args.allow_failed, args.refits)
    for line in selection.table():
        print(line)
    run = run_selected(config, selection, args.output, force=args.force, allow_failed=args.allow_failed)
    print(f"\nChosen: {selection.rungs[selection.chosen].name}, fitted on all samples:\n")
    return print_run(run, args.quiet, selection.notes)


def add_parser(subparsers) -> None:
    s = subparsers.add_parser("select", help="choose a model by cross-validation (ladder + one-standard-error rule)")
    s.add_argument("config", help="calibration YAML; compliance / backlash / tilt it asks for extend the ladder")
    add_fold_arguments(s)
    add_run_arguments(s)
    s.set_defaults(handler=cmd_select)
