"""`run_calibration(setup, output_dir)`: fit a set-up and write its output folder, the one path that
`robocal calibrate`, `robocal select`, a fleet's units and Python scripts share.

In order: refuse an output folder that cannot be replaced and an ISO 9283 section that does not fit the
data (before any fitting time is spent), run the input checks (units, sigmas, repeated postures, quaternion order,
joint limits: workflows/input_checks.py), register the nominal
robot and fit, then write the folder atomically: result.json, summary.txt, the calibrated URDF (only for a
fit that is not refused, unless allow_failed), config.yaml (the config with absolute paths, which `robocal
evaluate` reads), scene.json (before = the registered nominal robot, after = the calibrated one), report.html
(the [viz] extra), iso9283.json when the config asks for ISO 9283 figures and hand_eye.json for camera blocks.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import yaml

from robocal.estimation.calibrate import calibrate
from robocal.estimation.camera_report import camera_summary
from robocal.estimation.result import CalibrationResult
from robocal.io.output_folder import check_replaceable
from robocal.viz.scene import scene_data, scene_json, scene_note
from robocal.workflows.input_checks import check_inputs
from robocal.workflows.iso9283 import check_iso9283, iso9283_run
from robocal.workflows.outputs import write_results
from robocal.workflows.setup import Setup


@dataclass
class CalibrationRun:
    """What run_calibration did: the result, the files written, warnings a user must read (a units mix-up
    let through by allow_failed, a rejected fit) and notes (a scene drawing a subset, a report left out)."""

    setup: Setup
    result: CalibrationResult
    files: dict[str, Path]
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    rejected: str = ""              # why an accepted-looking fit was rejected (accept_sigma_ratio), else ""

    @property
    def urdf_written(self) -> bool:
        return any(name.endswith(".urdf") for name in self.files)


def sigma_ratio(result: CalibrationResult) -> float:
    """RMS of the weighted residual over the degrees of freedom: 1 when the data scatter as their sigmas say."""
    return float(np.sqrt(np.sum(result.solve.fun ** 2) / max(result.dof, 1)))


def run_calibration(setup: Setup, output_dir: str | Path | None = None, *, force: bool = False,
                    allow_failed: bool = False, report: bool | None = None, progress: Callable | None = None,
                    extra: dict[str, bytes] | None = None, accept_sigma_ratio: float | None = None,
                    source: str | None = None, fitted: tuple | None = None) -> CalibrationRun:
    """Fit `setup` and write its output folder (default: the config's output.dir); see the module docstring.

    report None follows the config's output.report; extra: more files for the folder (selection.json);
    accept_sigma_ratio: a converged fit whose residual/sigma exceeds it writes no URDF (a fleet's accept rule);
    progress: called with each solver iteration; fitted: (nominal ParameterSet, CalibrationResult) of a
    `calibrate(setup.problem, setup.options)` already run on this setup, whose inputs were checked (robocal select
    fits every rung: the chosen one is not fitted twice). Raises InputError (nothing written) for bad input."""
    out = Path(output_dir).resolve() if output_dir is not None else setup.output_dir
    check_replaceable(out, force)
    if setup.config.iso9283 is not None:
        check_iso9283(setup)                     # a mistake there costs no fitting time
    problem = setup.problem
    if fitted is None:
        warnings, notes = check_inputs(setup, allow_failed), []
        nominal = problem.params.copy()
        result = calibrate(problem, setup.options, progress=progress,
                           source=source or ", ".join(str(t.path) for t in setup.tables.values()))
    else:
        (nominal, result), warnings, notes = fitted, [], []
    rejected = ""
    if accept_sigma_ratio is not None and result.solve.success and sigma_ratio(result) > accept_sigma_ratio:
        rms = "; ".join(f"{b.name} " + ", ".join(f"{v:.4g} {k}" for k, v in b.rms.items()) for b in result.after)
        rejected = (f"residual/sigma {sigma_ratio(result):.4g} exceeds accept.max_sigma_ratio {accept_sigma_ratio:g} "
                    f"(RMS after the fit: {rms}); the fitted model does not explain the data")
        warnings.append(rejected + "; no calibrated URDF written")
    note = scene_note(setup)
    if note:
        notes.append(note)
    scene = scene_data(setup, result, result.registered_nominal(nominal))
    files = {"config.yaml": yaml.safe_dump(setup.config.to_dict(), sort_keys=False).encode(),
             "scene.json": scene_json(scene)}
    if setup.cameras:               # the hand-eye and intrinsics as a camera user reads them (docs/camera.md)
        cams = {name: camera_summary(problem, c) for name, c in setup.cameras.items()}
        files["hand_eye.json"] = (json.dumps(cams, indent=2) + "\n").encode()
        notes += [f"{name}: {n}" for name, c in setup.cameras.items() for n in c.notes]
    iso = None
    if setup.config.iso9283 is not None:
        iso = iso9283_run(setup, nominal, problem.params, result).to_dict()
        files["iso9283.json"] = (json.dumps(iso, indent=2) + "\n").encode()
    if setup.config.output.report if report is None else report:
        page, why = report_page(result, scene, iso)     # the scene in memory, not parsed back from its JSON
        if page is not None:
            files["report.html"] = page
        else:
            notes.append(why)
    files.update(extra or {})
    written = write_results(setup.robot, result, out, force=force, allow_failed=allow_failed and not rejected,
                            extra=files, urdf=not rejected)
    return CalibrationRun(setup, result, written, warnings, notes, rejected)


def report_page(result, scene: dict, iso: dict | None) -> tuple[bytes | None, str]:
    """(report.html, "") or (None, why it is missing): it needs the optional [viz] extra."""
    try:
        from robocal.viz.report import report_bytes   # the optional [viz] extra (meshcat's viewer script)
    except ImportError as exc:
        return None, f"no report.html ({exc.name} is not installed: pip install 'robocal[viz]')"
    return report_bytes(result, scene, meshes=False, iso9283=iso), ""      # meshes=False: 1.5 MB, not 10

