"""The `robocal` command: argument parsing and terminal output only; the work is done by the library."""
