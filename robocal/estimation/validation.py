"""Scoring a calibrated model on another session, and cross-validation with figures per fold.

`norm_errors(block)` turns one block's term errors into error norms per point / orientation (mm, mrad);
`evaluate_result(result_dir, csv, config)` scores a calibrated output folder on another CSV of the same
columns (only the parameters the user marks as re-registered per session are refitted) and sorts the
samples inside / outside the training joint ranges; `group_folds` builds leave-one-group-out folds from
a CSV column; `cv_table` fits each fold and reports train and validation norm RMS per fold and overall
with standard errors. See docs/validation.md. The library never prints.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from robocal.errors import InputError
from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.evaluation import (RANGE_MARGIN, BlockErrors, kfold, range_excess, setup_for_data,
                                           subset_residual, term_errors)
from robocal.estimation.problem import Problem
from robocal.estimation.registration import fit_subset
from robocal.io.data_check import units_findings

UNITS = {"length": (1e3, "mm", "3D position error"), "angle": (1e3, "mrad", "3D orientation error")}


def norm_errors(block: BlockErrors) -> dict[str, np.ndarray]:
    """{unit kind: (n_terms, k) error norms in mm / mrad}: triples of rows of one kind -> 3D norm, else |row|."""
    units = np.array(block.row_units)
    out = {}
    for kind in dict.fromkeys(block.row_units):
        scale = UNITS.get(kind, (1.0, kind, kind))[0]
        cols = block.raw[:, units == kind] * scale
        out[kind] = (np.linalg.norm(cols.reshape(len(cols), -1, 3), axis=2) if cols.shape[1] % 3 == 0
                     else np.abs(cols))
    return out


def norm_rms(values: np.ndarray) -> dict:
    v = np.asarray(values, float).reshape(-1)
    if not len(v):
        return {"n": 0, "rms_norm": None, "max_norm": None}
    return {"n": int(len(v)), "rms_norm": float(np.sqrt(np.mean(v ** 2))), "max_norm": float(np.max(v))}


def primary_errors(blocks: dict[str, BlockErrors]) -> tuple[np.ndarray, np.ndarray, str]:
    """(samples, norms) of every length point of every block (mm) or, without lengths, of the angles (mrad)."""
    for kind in ("length", "angle"):
        samples, norms = [], []
        for b in blocks.values():
            e = norm_errors(b).get(kind)
            if e is not None:
                samples.append(np.repeat(b.samples[:, None], e.shape[1], 1).reshape(-1) if b.samples.ndim == 1
                               else np.repeat(b.samples[:, :1], e.shape[1], 1).reshape(-1))
                norms.append(e.reshape(-1))
        if norms:
            return np.concatenate(samples), np.concatenate(norms), UNITS[kind][1]
    raise InputError("no length or angle measurement to score")


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


# ---------------------------------------------------------------- cross-validation
def group_folds(setup, column: str) -> list[np.ndarray]:
    """Leave-one-group-out folds: the samples sharing a value of `column` of the data CSV, in order of first
    appearance. A sample's group is read from the row it came from."""
    labels = []
    for file, row in setup.sample_rows:
        tab = setup.tables[file]
        if not tab.has(column):
            raise InputError(f"no group column '{column}' (columns present: {', '.join(tab.header)})",
                             source=str(tab.path), field=column)
        labels.append(tab.cells[row][tab.header.index(column)].strip())
    groups = list(dict.fromkeys(labels))
    if len(groups) < 2:
        raise InputError(f"column '{column}' holds a single group: nothing to hold out", field=column)
    labels = np.array(labels)
    return [np.flatnonzero(labels == g) for g in groups]


def make_folds(setup, folds: int | None = None, loo: bool = False, group: str | None = None):
    """(folds, description): `group` column -> leave-one-group-out, `loo` -> leave-one-out, else K interleaved
    folds (default 5, fold i = samples i, i + K, ...)."""
    n = len(setup.problem.values)
    if group:
        return group_folds(setup, group), f"leave-one-group-out on column '{group}'"
    if loo:
        return kfold(n, n), f"leave-one-out ({n} folds)"
    k = folds or min(5, n)
    if not 2 <= k <= n:
        raise InputError(f"need 2 <= folds <= {n} samples, got {k}", field="--folds")
    return kfold(n, k), f"{k}-fold"


@dataclass
class CVTable:
    unit: str
    folds: list[dict]             # per fold: n held out, train RMS, validation RMS
    rms: float                    # held-out norm RMS over every held-out point
    stderr: float                 # its standard error across folds (delta method on the per-fold mean squares)
    train_rms: float

    def to_dict(self) -> dict:
        return {"unit": self.unit, "validation_rms_norm": self.rms, "validation_rms_stderr": self.stderr,
                "train_rms_norm": self.train_rms, "folds": self.folds}


def cv_table(problem: Problem, folds: list[np.ndarray], options: CalibrationOptions | None = None) -> CVTable:
    """Fit on all samples outside each fold, score train and held-out norm errors; `problem` is unchanged."""
    opt = replace(options or CalibrationOptions(), register_before=False)
    initial = problem.params.copy()
    n = len(problem.values)
    rows, held_sq, train_sq, unit = [], [], [], ""
    for fold in folds:
        train = np.setdiff1d(np.arange(n), fold)
        params = initial.copy()
        sub = Problem(problem.robot, params, problem.joint_names, problem.values,
                      [subset_residual(r, train) for r in problem.residuals], problem.directions)
        result = calibrate(sub, opt)
        _, tr, unit = primary_errors(term_errors(sub))
        _, va, _ = primary_errors(term_errors(problem, params, [subset_residual(r, fold) for r in problem.residuals]))
        held_sq.append(va ** 2)
        train_sq.append(tr ** 2)
        rows.append({"held_out_samples": [int(i) for i in fold], "train_rms_norm": float(np.sqrt(np.mean(tr ** 2))),
                     "validation_rms_norm": float(np.sqrt(np.mean(va ** 2))) if len(va) else None,
                     "status": result.status})
    allsq = np.concatenate(held_sq)
    rms = float(np.sqrt(np.mean(allsq)))
    # per-fold mean squares weighted by size; standard error of their mean, then d sqrt(x) = dx / (2 sqrt(x))
    per = np.array([np.mean(h) for h in held_sq if len(h)])
    se_ms = float(np.std(per, ddof=1) / np.sqrt(len(per))) if len(per) > 1 else float("nan")
    return CVTable(unit, rows, rms, se_ms / (2 * rms) if rms > 0 else float("nan"),
                   float(np.sqrt(np.mean(np.concatenate(train_sq)))))
