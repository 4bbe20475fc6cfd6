"""`robocal cv CONFIG [--folds K | --loo] [--group COLUMN]`: cross-validate a calibration (docs/validation.md)."""
from __future__ import annotations

import sys

from robocal.estimation.leave_out import FitFailed
from robocal.workflows.cv import run_cv


def cmd_cv(args) -> int:
    try:
        table, label, notes = run_cv(args.config, args.folds, args.loo, args.group, args.allow_failed, args.refits)
    except FitFailed as failed:
        print(f"robocal: {failed}: no fold figure is worth refitting for a model its own data cannot fit. Fix the "
              "fit first (`robocal calibrate` prints why and how), or pass --allow-failed (or --refits) to refit "
              "every fold anyway.", file=sys.stderr)
        for line in failed.result.refusal_lines():
            print(f"robocal: {line}", file=sys.stderr)
        return 3
    for note in notes:
        print(f"robocal: {note}", file=sys.stderr)
    u = table.unit
    if args.quiet:
        print(f"held-out RMS {table.rms:.4g} {u} +- {table.stderr:.2g} {u} ({label})")
        return 0
    print(f"Cross-validation of {args.config}, {label}: RMS of the error norm ({u}), each fold predicted "
          "without its samples")
    print(f"  {'fold':>4}{'held out':>10}{'train RMS':>12}{'held-out RMS':>14}  status")
    for k, f in enumerate(table.folds, 1):
        va = f"{f['validation_rms_norm']:.4g}" if f["validation_rms_norm"] is not None else "n/a"
        print(f"  {k:>4}{len(f['held_out_samples']):>10}{f['train_rms_norm']:>12.4g}{va:>14}  {f['status']}")
    print(f"Overall: train RMS {table.train_rms:.4g} {u}, held-out RMS {table.rms:.4g} {u} "
          f"+- {table.stderr:.2g} {u} (standard error across folds)")
    for unit, v in table.others.items():
        print(f"         orientation: train RMS {v['train']:.4g} {unit}, held-out RMS {v['rms']:.4g} {unit} "
              f"+- {v['stderr']:.2g} {unit}")
    return 0


def add_fold_arguments(parser) -> None:
    """--folds K | --loo | --group COLUMN (shared by cv and select)."""
    how = parser.add_mutually_exclusive_group()
    how.add_argument("--folds", type=int, help="K folds of whole postures (default 5; with sessions: one per "
                                                "session)")
    how.add_argument("--loo", action="store_true", help="leave one posture out (repeats of a posture together)")
    how.add_argument("--group", metavar="COLUMN", help="leave one group out: samples sharing this CSV column's value")
    parser.add_argument("--refits", action="store_true", help="refit every fold instead of the closed-form leave-out "
                                                              "update of the fit on all samples")


def add_parser(subparsers) -> None:
    c = subparsers.add_parser("cv", help="cross-validate a calibration config (K-fold, leave-one-out or grouped)")
    c.add_argument("config", help="calibration YAML (docs/config.md)")
    add_fold_arguments(c)
    c.add_argument("--allow-failed", action="store_true", help="go on despite implausible data (a units mix-up) or "
                                                                "a fit on all samples that fails (the folds refitted)")
    c.set_defaults(handler=cmd_cv)
