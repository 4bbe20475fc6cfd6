"""The `robocal` command: one sub-command per module of robocal.cli, registered in COMMANDS.

Only robocal.cli writes to the terminal; the library logs. A new command is a module here with
`add_parser(subparsers)` (which sets `handler`) and its names in COMMANDS.

A command's module is imported only when that command runs: each one imports its part of the library
(the fit, the dynamics stack, Dask), and `robocal --version` or `robocal calibrate` should not wait for the
others. The other commands are listed by name and help text only (tests/test_cli.py checks that COMMANDS
says what the modules register).
"""
from __future__ import annotations

import argparse
import gc
import logging
import sys
from importlib import import_module

import numpy as np

from robocal.errors import RobocalError
from robocal.io.output_folder import robocal_version

#: sub-command -> (its module in robocal.cli, its help line), in the order `robocal --help` lists them
COMMANDS = {
    "calibrate": ("calibrate", "fit a robot model to measurements described by a YAML config"),
    "demo": ("calibrate", "calibrate a simulated UR5 from built-in data"),
    "simulate": ("simulate", "write a synthetic dataset (and its truth) from a YAML config"),
    "plan": ("plan", "choose poses to measure and predict the calibration's accuracy"),
    "iso9283": ("iso9283", "ISO 9283 accuracy and repeatability, nominal and calibrated"),
    "view": ("view", "show a calibration result in meshcat (or write it as a static HTML page)"),
    "report": ("view", "write the HTML report of a calibration result"),
    "evaluate": ("evaluate", "score a calibrated model (output folder) on another session, or predict a new "
                             "log's torques with an identified dynamic model"),
    "cv": ("cv", "cross-validate a calibration config (K-fold, leave-one-out or grouped)"),
    "select": ("select", "choose a model by cross-validation (ladder + one-standard-error rule)"),
    "identify": ("identify", "identify inertial and friction parameters from a joint log (positions, velocities, "
                             "efforts; or motor encoders and currents through a transmission: docs/dynamics_tiago.md, "
                             "docs/dynamics_motors.md)"),
    "fleet": ("fleet", "calibrate many units on Dask into one table; compare them"),
}


def command_module(module: str):
    """The robocal.cli module of one command, imported now (see the module docstring; the one import by name
    that tests/test_architecture.py allows besides robocal.viz's optional names)."""
    return import_module(f"robocal.cli.{module}")


def requested(argv: list[str]) -> str | None:
    """The sub-command named on the command line (the global options are flags: the first word is it)."""
    return next((a for a in argv if not a.startswith("-")), None)


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser; with `argv`, only the module of the command it names is imported (every other command is
    a name and a help line), without it every command's module is."""
    parser = argparse.ArgumentParser(prog="robocal", description="Calibrate robot models from measurements.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log library messages")
    parser.add_argument("--version", action="version", version=f"robocal {robocal_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    wanted = None if argv is None else COMMANDS.get(requested(argv), (None,))[0]
    loaded: set[str] = set()
    for name, (module, help_line) in COMMANDS.items():
        if name in sub.choices:
            continue
        if argv is None or module == wanted:
            if module not in loaded:
                command_module(module).add_parser(sub)
                loaded.add(module)
        else:
            sub.add_parser(name, help=help_line)
    for p in subcommands(parser):
        if not any("--quiet" in a.option_strings for a in p._actions):
            p.add_argument("-q", "--quiet", action="store_true", help="print only errors and the result")
    return parser


def subcommands(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """Every leaf sub-command parser (`robocal fleet run` is one, `robocal fleet` is not)."""
    out = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for p in action.choices.values():
                out += subcommands(p) or [p]
    return out


def main(argv: list[str] | None = None) -> int:
    process = argv is None              # the `robocal` command itself, not a call from Python
    argv = sys.argv[1:] if argv is None else list(argv)
    # Loading a command's modules allocates much and frees little: without the cyclic collector meanwhile,
    # ~25 ms less start-up (benchmarks/startup.py)
    gc.disable()
    try:
        parser = build_parser(argv)
    finally:
        gc.enable()
    args = parser.parse_args(argv)
    level = logging.INFO if args.verbose else logging.ERROR if args.quiet else logging.WARNING
    logging.basicConfig(level=level, format="%(name)s: %(message)s")
    np.set_printoptions(precision=6, suppress=True)
    try:
        return args.handler(args)
    except RobocalError as exc:
        print(f"robocal: error: {exc}", file=sys.stderr)
        return 2
    finally:
        if process:     # the process ends now: Python's collection at exit would walk every object the
            gc.freeze()  # command's modules made, 0.1-0.2 s of CPU after scipy's (benchmarks/workflow_timing.py)


if __name__ == "__main__":
    sys.exit(main())
