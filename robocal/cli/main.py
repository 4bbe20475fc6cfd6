"""The `robocal` command: one sub-command per module of robocal.cli, registered in COMMANDS.

Only robocal.cli writes to the terminal; the library logs. A new command is a module here with
`add_parser(subparsers)` (which sets `handler`) and one entry in COMMANDS.
"""
from __future__ import annotations

import argparse
import logging
import sys

import numpy as np

from robocal.cli import calibrate, fleet, iso9283, plan, simulate, view
from robocal.errors import RobocalError

COMMANDS = (calibrate, simulate, plan, iso9283, view, fleet)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="robocal", description="Calibrate robot models from measurements.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log library messages")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(name)s: %(message)s")
    np.set_printoptions(precision=6, suppress=True)
    try:
        return args.handler(args)
    except RobocalError as exc:
        print(f"robocal: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
