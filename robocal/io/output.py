"""The output folder of a calibration: calibrated URDF, result JSON, summary text.

Everything is written into a temporary folder beside the target, which is renamed into place only
when complete: a failure leaves no half-written output behind.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from robocal.errors import InputError
from robocal.io.urdf_export import calibrated_urdf


def write_folder(out_dir: str | Path, files: dict[str, bytes], force: bool = False) -> dict[str, Path]:
    """Write {file name: content} as the folder `out_dir`, atomically: the files go into a temporary
    folder beside it, which replaces `out_dir` (only with force=True if it exists) once all are written."""
    out = Path(out_dir).resolve()
    if out.exists() and not force:
        raise InputError("output folder exists; pass --force to replace it", source=str(out))
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}."))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)   # mkdtemp makes it private; the result is an ordinary folder
    try:
        for name, content in files.items():
            (tmp / name).write_bytes(content)
        if out.exists():
            old = out.with_name(f".{out.name}.old")
            shutil.rmtree(old, ignore_errors=True)
            out.rename(old)
            tmp.rename(out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {name: out / name for name in files}


def write_results(robot, result, out_dir: str | Path, force: bool = False, allow_failed: bool = False,
                  extra: dict[str, bytes] | None = None) -> dict[str, Path]:
    """Write result.json, summary.txt and (for a successful fit) the calibrated URDF.

    Returns {file name: final path}. An existing folder is replaced only with force=True.
    """
    out = Path(out_dir).resolve()
    if robot.urdf_path is not None and Path(robot.urdf_path).resolve().parent == out:
        raise InputError("the output folder holds the input URDF; choose another folder", source=str(out))
    files = {"result.json": (result.to_json() + "\n").encode(), "summary.txt": (result.summary() + "\n").encode()}
    if robot.urdf_text and (result.success or allow_failed):
        name = f"{Path(robot.urdf_path).stem if robot.urdf_path else robot.name}_calibrated.urdf"
        files[name] = calibrated_urdf(robot, result.params)
    files.update(extra or {})
    return write_folder(out, files, force)
