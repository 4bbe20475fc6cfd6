"""YAML files read with errors that name the file and the line."""
from __future__ import annotations

from pathlib import Path

import yaml

from robocal.errors import InputError


def read_yaml(path: Path):
    """The parsed YAML file, or an InputError naming the file and line."""
    path = Path(path)
    if not path.is_file():
        raise InputError("config file not found", source=str(path))
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise InputError(f"not a text file ({exc.reason})", source=str(path)) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        if line is None and isinstance(getattr(exc, "position", None), int):   # a ReaderError: a bad character
            line = path.read_text(encoding="utf-8", errors="replace")[:exc.position].count("\n") + 1
        where = "" if line is None else f" at line {line}"
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"not valid YAML{where}: {problem}", source=str(path)) from None
