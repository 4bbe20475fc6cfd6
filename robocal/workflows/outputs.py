"""The files of a calibration's output folder: result.json, summary.txt, the calibrated URDF and extras."""
from __future__ import annotations

from pathlib import Path

from robocal.errors import InputError
from robocal.io.output_folder import write_folder
from robocal.model.urdf_export import calibrated_urdf


def write_results(robot, result, out_dir: str | Path, force: bool = False, allow_failed: bool = False,
                  extra: dict[str, bytes] | None = None) -> dict[str, Path]:
    """Write result.json, summary.txt and (for a successful fit) the calibrated URDF.

    Returns {file name: final path}. An existing folder is replaced only with force=True, and only if
    robocal wrote it.
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
