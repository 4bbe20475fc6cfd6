"""Output folders written whole or not at all, with a manifest of what robocal wrote.

Everything is written into a fresh temporary folder beside the target, which is renamed into place
only when complete: a failure leaves no half-written output behind. The folder gets a manifest
(MANIFEST) listing the files robocal wrote; `--force` replaces only such a folder, and refuses one
that holds anything else (a user's own files are never deleted).
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from robocal.errors import InputError
from robocal.io.text_files import write_atomic

MANIFEST = ".robocal-manifest.json"
_SHOWN = 5   # foreign files named in the refusal


def robocal_version() -> str:
    try:
        return version("robocal")
    except PackageNotFoundError:   # running from a checkout that is not installed
        return "unknown"


def check_replaceable(out_dir: str | Path, force: bool) -> None:
    """Raise InputError unless `out_dir` is absent, or (with force) a folder that holds only what robocal
    wrote there (its manifest's files). Called before any work, and again just before the swap."""
    out = Path(out_dir).resolve()
    if not out.exists() and not out.is_symlink():
        return
    if not force:
        raise InputError("output folder exists; pass --force to replace it", source=str(out))
    if not out.is_dir() or out.is_symlink():
        raise InputError("exists and is not a folder robocal wrote; it is left alone (remove it or choose "
                         "another output)", source=str(out))
    try:
        listed = set(json.loads((out / MANIFEST).read_text(encoding="utf-8"))["files"])
        has_manifest = True
    except (OSError, ValueError, KeyError, TypeError):
        listed, has_manifest = set(), False
    foreign = []
    for p in sorted(out.rglob("*")):
        rel = p.relative_to(out).as_posix()
        if rel == MANIFEST or rel in listed:
            continue
        if p.is_dir() and not p.is_symlink() and any(f.startswith(rel + "/") for f in listed):
            continue
        foreign.append(rel)
    more = f" and {len(foreign) - _SHOWN} more" if len(foreign) > _SHOWN else ""
    names = ", ".join(foreign[:_SHOWN]) + more
    if not has_manifest:
        raise InputError(f"--force replaces only a folder robocal wrote, and this one has no {MANIFEST}"
                         + (f" (it holds {names})" if foreign else "")
                         + "; remove it yourself or choose another output folder", source=str(out))
    if foreign:
        raise InputError(f"the folder holds files robocal did not write ({names}); --force replaces only what "
                         "robocal wrote: move them or choose another output folder", source=str(out))


def add_to_manifest(path: str | Path) -> None:
    """Record a file robocal has added to one of its output folders (`robocal report` writes report.html into
    a result folder), so that --force may later replace the folder with it; a folder without a manifest is
    left as it is."""
    path = Path(path).resolve()
    manifest = path.parent / MANIFEST
    try:
        doc = json.loads(manifest.read_text(encoding="utf-8"))
        files = set(doc["files"])
    except (OSError, ValueError, KeyError, TypeError):
        return
    doc["files"] = sorted(files | {path.name})
    write_atomic(manifest, json.dumps(doc, indent=2) + "\n")


def write_folder(out_dir: str | Path, files: dict[str, bytes], force: bool = False) -> dict[str, Path]:
    """Write {file name: content} as the folder `out_dir`, atomically: the files and the manifest go into a
    temporary folder beside it, which replaces `out_dir` (see check_replaceable) once all are written."""
    out = Path(out_dir).resolve()
    check_replaceable(out, force)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}."))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)   # mkdtemp makes it private; the result is an ordinary folder
    manifest = {"written_by": f"robocal {robocal_version()}", "files": sorted(files)}
    try:
        for name, content in files.items():
            (tmp / name).parent.mkdir(parents=True, exist_ok=True)
            (tmp / name).write_bytes(content)
        (tmp / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
        if out.exists():
            check_replaceable(out, force)     # the folder may have changed during the run
            old = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.old."))
            old.rmdir()
            out.rename(old)
            tmp.rename(out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {name: out / name for name in files}
