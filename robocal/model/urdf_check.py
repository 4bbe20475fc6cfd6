"""Checks of a URDF before Pinocchio reads it, and the capture of urdfdom's own error output.

urdfdom (Pinocchio's URDF parser) prints its complaints to the C-level stderr and then fails with a
generic message. robocal checks what urdfdom would reject first, naming the element and its line, and
captures whatever urdfdom still prints so that it becomes part of robocal's one-line message.
"""
from __future__ import annotations

import os
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from robocal.errors import InputError


def check_urdf_elements(tree, path: Path) -> None:
    """What urdfdom would reject, named by line before it prints its own C++ errors to the terminal."""
    links = {e.get("name") for e in tree.iter("link")}
    if not links:
        raise InputError("not a URDF: it has no <link> element", source=str(path))
    for kind in ("link", "joint"):
        for e in tree.iter(kind):
            if e.getparent() is tree and not e.get("name"):
                raise InputError(f"<{kind}> at line {e.sourceline} has no name attribute", source=str(path))
    for j in tree.iter("joint"):
        if j.getparent() is not tree:
            continue
        if j.get("type") not in ("revolute", "continuous", "prismatic", "fixed", "floating", "planar"):
            raise InputError(f"joint '{j.get('name')}' (line {j.sourceline}) has type '{j.get('type')}'; "
                             "expected revolute, continuous, prismatic, fixed, floating or planar",
                             source=str(path), field=f"joint {j.get('name')}")
        limit = j.find("limit")
        if j.get("type") in ("revolute", "prismatic") and (limit is None or limit.get("effort") is None
                                                           or limit.get("velocity") is None):
            raise InputError(f"joint '{j.get('name')}' (line {j.sourceline}) needs <limit effort=... velocity=...> "
                             "(and lower, upper)", source=str(path), field=f"joint {j.get('name')}")
        for tag in ("parent", "child"):
            e = j.find(tag)
            if e is None or e.get("link") not in links:
                raise InputError(f"joint '{j.get('name')}' (line {j.sourceline}): <{tag} link=...> names no link "
                                 f"of this file", source=str(path), field=f"joint {j.get('name')}")
    for e in tree.iter("origin", "axis", "limit"):
        for attr in ("xyz", "rpy", "lower", "upper", "effort", "velocity"):
            text = e.get(attr)
            if text is None:
                continue
            try:
                values = [float(v) for v in text.split()]
            except ValueError:
                values = []
            if not values or not all(np.isfinite(values)) or (attr in ("xyz", "rpy") and len(values) != 3):
                raise InputError(f"<{e.tag} {attr}=\"{text}\"> at line {e.sourceline} is not "
                                 f"{'three numbers' if attr in ('xyz', 'rpy') else 'a number'}", source=str(path),
                                 field=f"{e.tag}.{attr}")


@contextmanager
def c_stderr_captured():
    """Capture what C++ code writes to file descriptor 2 (urdfdom prints its errors there), so it does not
    leak to the terminal ahead of robocal's own message; yields a list that receives the text."""
    captured: list[str] = []
    fd = 2                    # C++ writes to descriptor 2 whatever Python's sys.stderr is at the moment
    try:
        sys.stderr.flush()
    except (AttributeError, OSError, ValueError):
        pass
    saved = os.dup(fd)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), fd)
        try:
            yield captured
        finally:
            os.dup2(saved, fd)
            os.close(saved)
            tmp.seek(0)
            captured.append(tmp.read().decode("utf-8", errors="replace"))
