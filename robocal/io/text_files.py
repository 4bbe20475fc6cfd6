"""Numbers as text and files written whole: the one place robocal formats a float for a file.

Numbers are written with 15 significant digits (a double round-trips to ~1e-15 relative), round-off
dust below 1e-15 in magnitude as 0, and never as "-0". This makes the text a deterministic function
of the numbers; numbers computed with transcendental functions can still differ in their last bits
between CPUs and libm versions, so tests compare written files number by number with a stated
tolerance (`robocal.io.text_files.numbers_in`), not byte by byte.
"""
from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

import numpy as np

SIGNIFICANT_DIGITS = 15
DUST = 1e-15
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def format_number(value) -> str:
    """One float as text: 15 significant digits, dust as 0, no negative zero."""
    v = float(value)
    if abs(v) < DUST:
        return "0"
    return "%.*g" % (SIGNIFICANT_DIGITS, v)


def format_numbers(values) -> str:
    """Space-separated numbers (a scalar or any array), as URDF attributes hold them."""
    return " ".join(format_number(v) for v in np.atleast_1d(np.asarray(values, dtype=float)).ravel())


def numbers_in(text: str) -> tuple[str, np.ndarray]:
    """Split text into its non-number skeleton (numbers replaced by '#') and the numbers, for comparisons
    of written files with a tolerance on the numbers and exactness on everything else."""
    values = [float(m) for m in _NUMBER.findall(text)]
    return _NUMBER.sub("#", text), np.asarray(values)


def write_atomic(path: str | Path, content: bytes | str) -> Path:
    """Write a whole file or nothing: into a temporary file beside it, then renamed into place."""
    path = Path(path)
    data = content.encode("utf-8") if isinstance(content, str) else content
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
