"""Exceptions. Every input problem names where it came from: file, row, field."""
from __future__ import annotations


class RobocalError(Exception):
    """Base class of every error robocal raises on purpose."""


class InputError(RobocalError, ValueError):
    """Bad user input: a config key, a data cell, a URDF element.

    `source` is the file (or "config"), `row` the 1-based line in that file when it
    applies, `field` the key or column name.
    """

    def __init__(self, message: str, source: str | None = None, row: int | None = None,
                 field: str | None = None):
        self.source, self.row, self.field, self.reason = source, row, field, message
        where = []
        if source:
            where.append(str(source))
        if row is not None:
            where.append(f"row {row}")
        if field:
            where.append(f"field '{field}'")
        super().__init__((": ".join([", ".join(where), message])) if where else message)


class FrameNotFound(InputError):
    """A frame name the robot does not have; the message lists close matches."""


class AssemblyError(RobocalError):
    """A closed chain could not be assembled (unreachable or singular readings)."""


class IdentifiabilityError(RobocalError):
    """The data cannot determine the parameters asked for (too few measurements)."""
