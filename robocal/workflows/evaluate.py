"""`robocal evaluate`: score a calibrated output folder on another session of the same columns.

`evaluate_result(result_dir, csv, config)` rebuilds the config's problem on `csv`, sets the folder's
parameter values, refits only the parameters the user marks as re-registered per session, and sorts the
samples inside / outside the training joint ranges. `setup_for_data` builds a config's problem on another
CSV file.
See docs/validation.md.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robocal.errors import InputError
from robocal.estimation.calibrate import CalibrationOptions
from robocal.estimation.cross_validation import RANGE_MARGIN, range_excess
from robocal.estimation.registration import fit_subset
from robocal.estimation.prediction_errors import UNITS, norm_errors, norm_rms, term_errors
from robocal.io.tables import read_csv
from robocal.workflows.config_camera import camera_detections, with_camera_frames_of, with_detections
from robocal.workflows.config_read import read_config, with_parameters
from robocal.workflows.config_types import CalibrationConfig
from robocal.workflows.setup import Setup, build_setup
from robocal.io.output_folder import write_folder
from robocal.workflows.data_check import units_findings
from robocal.workflows.outputs import apply_result, load_result


def setup_for_data(config, csv: str | Path | None = None, parameters: dict | None = None,
                   detections: dict[str, Path] | None = None) -> Setup:
    """A config's problem (a YAML path or a CalibrationConfig), optionally on another CSV file of the same
    columns, with changed parameters, and with other detections files for its camera blocks.

    csv replaces `data.csv` and every block's `csv` (absolute, or relative to the config's folder);
    parameters: keys of the `parameters:` section replaced, in their YAML form (e.g. {"preset": "offsets"});
    detections: {camera block name: its detections CSV for the images of `csv`}.
    """
    config = config if isinstance(config, CalibrationConfig) else read_config(config)
    if parameters:
        config = with_parameters(config, parameters)
    if detections:
        config = with_detections(config, detections)
    table = None if csv is None else read_csv((config.base_dir / csv).resolve())
    return build_setup(config, table=table)


@dataclass
class EvaluationReport:
    data: str
    refitted: list[str]
    blocks: list[dict]
    per_sample: list[dict]
    outside: list[dict]

    def to_dict(self) -> dict:
        return {"data": self.data, "refitted": self.refitted, "blocks": self.blocks, "per_sample": self.per_sample,
                "outside_training_range": self.outside,
                "units": "norm of the 3D error per point (mm) or orientation (mrad)"}


def evaluate_result(result_dir, csv, config, refit: list[str] | None = None,
                    options: CalibrationOptions | None = None,
                    detections: dict[str | None, Path] | None = None) -> EvaluationReport:
    """Score the model of `result_dir` on `csv` (columns as in `config`); refit only the `refit` patterns.
    detections: the new images' detections file of each camera block ({None: file} when there is one block)."""
    result, source = load_result(result_dir)
    config = config if isinstance(config, CalibrationConfig) else read_config(config)
    detections = camera_detections(config, detections)
    train = setup_for_data(config)
    if detections:
        config = with_camera_frames_of(config, train)
    setup = setup_for_data(config, csv, detections=detections)
    findings = units_findings(setup)      # the other session in the config's units, as calibrate checks
    if findings:
        raise findings[0]
    params = setup.problem.params
    apply_result(params, result, source)
    refitted = []
    for pattern in refit or []:
        try:
            refitted += params.select(pattern)
        except InputError as exc:
            raise InputError(exc.reason, source="--refit", field=pattern) from None
    if refitted:
        fit_subset(setup.problem, list(dict.fromkeys(refitted)), options or setup.options)
    errors = term_errors(setup.problem)
    excess = range_excess(train.problem.values, setup.problem.values)
    outside = np.any(np.abs(excess) > RANGE_MARGIN, axis=1)
    blocks, per_sample = [], {}
    for name, b in errors.items():
        for kind, e in norm_errors(b).items():
            scale, unit, label = UNITS.get(kind, (1.0, kind, kind))
            s = b.samples if b.samples.ndim == 1 else b.samples[:, 0]
            entry = {"name": name, "norm_of": label, "unit": unit, "all": norm_rms(e),
                     "inside_training_range": norm_rms(e[~outside[s]]),
                     "outside_training_range": norm_rms(e[outside[s]])}
            if kind == "length" and e.shape[1] > 1 and len(b.labels) == e.shape[1]:
                # a rigid body's points one by one: the figure of each is what a single-point protocol scores
                entry["points"] = {lab: norm_rms(e[:, j]) for j, lab in enumerate(b.labels)}
            if name in setup.cameras:       # a camera's images one by one, by their labels: a bad image shows
                images = setup.cameras[name].labels
                entry["images"] = {images[int(i)]: norm_rms(e[s == i]) for i in np.unique(s)}
            blocks.append(entry)
            for k, i in enumerate(s):      # a sample's every term (a camera image: one per corner)
                per_sample.setdefault(int(i), {"sample": int(i), "csv_line": setup.sample_rows[int(i)][1] + 2,
                                               "outside_training_range": bool(outside[i])}).setdefault(
                    f"{name} {label} ({unit})", []).extend(float(v) for v in e[k])
    joints = setup.problem.joint_names
    far = [{"sample": int(i), "csv_line": setup.sample_rows[int(i)][1] + 2,
            "beyond_range": {j: float(excess[i, k]) for k, j in enumerate(joints) if abs(excess[i, k]) > RANGE_MARGIN}}
           for i in np.flatnonzero(outside)]
    return EvaluationReport(str(Path(csv).resolve()), list(dict.fromkeys(refitted)), blocks,
                            [per_sample[k] for k in sorted(per_sample)], far)


def evaluation_name(data: str | Path, refitted: list[str]) -> str:
    """The file of one evaluation: one per session and refit choice (a refitted run never replaces a plain one)."""
    return f"evaluation_{Path(data).stem}" + ("_refit" if refitted else "") + ".json"


def write_evaluation(folder: str | Path, report: EvaluationReport) -> tuple[Path, str]:
    """Add the evaluation file to the output folder (and its report.html, when the [viz] extra is there),
    atomically; returns (its path, a note when report.html could not be updated, else "")."""
    folder = Path(folder).resolve()
    name = evaluation_name(report.data, report.refitted)
    files = {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}
    files[name] = (json.dumps(report.to_dict(), indent=2) + "\n").encode()
    note = ""
    if "report.html" in files:
        try:
            from robocal.viz.report import report_with_new_evaluations   # the optional [viz] extra
            files["report.html"] = report_with_new_evaluations(folder, [report.to_dict()])
        except ImportError as exc:
            note = f"report.html not updated ({exc.name} is not installed)"
    write_folder(folder, files, force=True)
    return folder / name, note
