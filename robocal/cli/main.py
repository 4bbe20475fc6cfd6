"""The `robocal` command: one sub-command per module of robocal.cli, registered in COMMANDS.

Only robocal.cli writes to the terminal; the library logs. A new command is a module here with
`add_parser(subparsers)` (which sets `handler`) and one entry in COMMANDS.
"""
from __future__ import annotations

import argparse
import logging
import sys

import numpy as np

from robocal.cli import calibrate, cv, evaluate, fleet, identify, iso9283, plan, select, simulate, view
from robocal.errors import RobocalError
from robocal.io.output_folder import robocal_version

COMMANDS = (calibrate, simulate, plan, iso9283, view, evaluate, cv, select, identify, fleet)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="robocal", description="Calibrate robot models from measurements.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log library messages")
    parser.add_argument("--version", action="version", version=f"robocal {robocal_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
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
    args = build_parser().parse_args(argv)
    level = logging.INFO if args.verbose else logging.ERROR if args.quiet else logging.WARNING
    logging.basicConfig(level=level, format="%(name)s: %(message)s")
    np.set_printoptions(precision=6, suppress=True)
    try:
        return args.handler(args)
    except RobocalError as exc:
        print(f"robocal: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
