"""The `robocal` command: argument parsing and terminal output only; the work is done by the library."""
from robocal.cli.main import main

__all__ = ["main"]
