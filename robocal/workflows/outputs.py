"""The files of a calibration's output folder: written (result.json, summary.txt, the calibrated URDF and
extras), and a result read back to set a model's parameters."""
from __future__ import annotations

import json
from pathlib import Path

from robocal.errors import InputError
from robocal.io.output_folder import write_folder
from robocal.model.urdf_export import calibrated_urdf


def write_results(robot, result, out_dir: str | Path, force: bool = False, allow_failed: bool = False,
                  extra: dict[str, bytes] | None = None, urdf: bool = True) -> dict[str, Path]:
    """Write result.json, summary.txt and (for a successful fit, and unless urdf=False) the calibrated URDF.

    Returns {file name: final path}. An existing folder is replaced only with force=True, and only if
    robocal wrote it.
    """
    out = Path(out_dir).resolve()
    if robot.urdf_path is not None and Path(robot.urdf_path).resolve().parent == out:
        raise InputError("the output folder holds the input URDF; choose another folder", source=str(out))
    files = {"result.json": (result.to_json() + "\n").encode(), "summary.txt": (result.summary() + "\n").encode()}
    if urdf and robot.urdf_text and (result.success or allow_failed):
        name = f"{Path(robot.urdf_path).stem if robot.urdf_path else robot.name}_calibrated.urdf"
        files[name] = calibrated_urdf(robot, result.params)
    files.update(extra or {})
    return write_folder(out, files, force)


# ---------------------------------------------------------------- evaluate
def load_result(result: str | Path) -> tuple[dict, Path]:
    """(the parsed result.json, its path) of an output folder, or of a result.json file itself."""
    path = Path(result)
    path = path / "result.json" if path.is_dir() or path.suffix != ".json" else path
    if not path.is_file():
        raise InputError("no result.json: not a robocal output folder", source=str(path))
    try:
        return json.loads(path.read_text(encoding="utf-8")), path
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", source=str(path), row=exc.lineno) from exc


def apply_result(params, result: dict, source: Path) -> None:
    """Set `params` to a result's values; every parameter of the result must exist here (same robot), except
    the frames of the result's own sessions (another session has its own)."""
    for i, p in enumerate(result.get("parameters", [])):
        if p.get("kind") == "session_frame" and p.get("name") not in params:
            continue
        if p.get("name") not in params:
            raise InputError(f"parameter '{p.get('name')}' is not in this config's model: the result comes from "
                             "another robot or model", source=str(source), field=f"parameters[{i}].name")
        params[p["name"]].value = float(p["value"])
