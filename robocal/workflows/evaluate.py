"""`robocal evaluate`: score a calibrated output folder on another session of the same columns.

`evaluate_result(result_dir, csv, config)` rebuilds the config's problem on `csv`, sets the folder's
parameter values, refits only the parameters the user marks as re-registered per session, and sorts the
samples inside / outside the training joint ranges. `setup_for_data` builds a config's problem on another
CSV file; `portable_config` writes a config that rebuilds the same model from an output folder.
See docs/validation.md.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from robocal.errors import InputError
from robocal.estimation.calibrate import CalibrationOptions
from robocal.estimation.cross_validation import RANGE_MARGIN, range_excess
from robocal.estimation.registration import fit_subset
from robocal.estimation.prediction_errors import UNITS, norm_errors, norm_rms, term_errors
from robocal.io.tables import read_csv
from robocal.io.yaml_files import read_yaml
from robocal.workflows.config import Setup, setup_from_config
from robocal.workflows.data_check import units_findings


def setup_for_data(config: str | Path, csv: str | Path | None = None, parameters: dict | None = None) -> Setup:
    """A config's problem, optionally on another CSV file of the same columns and with changed parameters.

    csv replaces `data.csv` and every block's `csv` (absolute, or relative to the config's folder);
    parameters: keys merged into the config's `parameters` section (e.g. {"priors": {...}}).
    """
    path = Path(config).resolve()
    raw = read_yaml(path)
    if parameters and isinstance(raw, dict):
        raw = {**raw, "parameters": {**(raw.get("parameters") or {}), **parameters}}
    table = None if csv is None else read_csv((path.parent / csv).resolve())
    return setup_from_config(raw, path.parent, str(path), table=table)

def portable_config(config: str | Path, parameters: dict | None = None) -> bytes:
    """The config's YAML with its file paths made absolute (robot.urdf, package_dirs, every csv) and
    `parameters` merged in: stored in an output folder, it rebuilds the same model from there
    (`robocal evaluate`)."""
    path = Path(config).resolve()
    raw = read_yaml(path)            # a fresh parse: edited below, never shared
    here = path.parent
    robot = raw.get("robot") or {}
    if "urdf" in robot:
        robot["urdf"] = str((here / robot["urdf"]).resolve())
    if robot.get("package_dirs"):
        robot["package_dirs"] = [str((here / d).resolve()) for d in robot["package_dirs"]]
    if (raw.get("data") or {}).get("csv"):
        raw["data"]["csv"] = str((here / raw["data"]["csv"]).resolve())
    for block in raw.get("measurements") or []:
        if isinstance(block, dict) and block.get("csv"):
            block["csv"] = str((here / block["csv"]).resolve())
    if parameters:
        raw["parameters"] = {**(raw.get("parameters") or {}), **parameters}
    return yaml.safe_dump(raw, sort_keys=False).encode()


# ---------------------------------------------------------------- evaluate
def load_result(result_dir: str | Path) -> tuple[dict, Path]:
    path = Path(result_dir) / "result.json"
    if not path.is_file():
        raise InputError("no result.json: not a robocal output folder", source=str(path))
    try:
        return json.loads(path.read_text(encoding="utf-8")), path
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", source=str(path), row=exc.lineno) from exc

def apply_result(params, result: dict, source: Path) -> None:
    """Set `params` to a result's values; every parameter of the result must exist here (same robot)."""
    for i, p in enumerate(result.get("parameters", [])):
        if p.get("name") not in params:
            raise InputError(f"parameter '{p.get('name')}' is not in this config's model: the result comes from "
                             "another robot or model", source=str(source), field=f"parameters[{i}].name")
        params[p["name"]].value = float(p["value"])

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
                    options: CalibrationOptions | None = None) -> EvaluationReport:
    """Score the model of `result_dir` on `csv` (columns as in `config`); refit only the `refit` patterns."""
    result, source = load_result(result_dir)
    train = setup_for_data(config)
    setup = setup_for_data(config, csv)
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
            blocks.append({"name": name, "norm_of": label, "unit": unit, "all": norm_rms(e),
                           "inside_training_range": norm_rms(e[~outside[s]]),
                           "outside_training_range": norm_rms(e[outside[s]])})
            for k, i in enumerate(s):
                per_sample.setdefault(int(i), {"sample": int(i), "csv_line": setup.sample_rows[int(i)][1] + 2,
                                               "outside_training_range": bool(outside[i])})[
                    f"{name} {label} ({unit})"] = [float(v) for v in e[k]]
    joints = setup.problem.joint_names
    far = [{"sample": int(i), "csv_line": setup.sample_rows[int(i)][1] + 2,
            "beyond_range": {j: float(excess[i, k]) for k, j in enumerate(joints) if abs(excess[i, k]) > RANGE_MARGIN}}
           for i in np.flatnonzero(outside)]
    return EvaluationReport(str(Path(csv).resolve()), list(dict.fromkeys(refitted)), blocks,
                            [per_sample[k] for k in sorted(per_sample)], far)
