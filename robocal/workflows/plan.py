"""Planning a calibration: which poses to measure, and how accurate the calibration will be.

The config is a calibration YAML (robot / data / parameters / measurements) plus a `plan:` section;
the data file need not exist (no measurements are read). All keys are optional:

    plan:
      frame: tool0            # tool frame whose accuracy is predicted (default: first measurement's frame)
      N: 30                   # poses to choose
      criterion: D            # D, E, A, I, O1 ... O5 (robocal.design.criteria)
      seed: 1                 # candidate and validation draws
      noise: {position: 5.0e-5, orientation: 5.0e-5}   # replaces every block's sigma (data units)
      candidates: {method: random, count: 1000, margin: 0.05,  # or method: grid, levels: 4 (or a list)
                   min_singular: 0.02, length_scale: 0.5}
      volume: {box: {min: [x, y, z], max: [x, y, z]}, sphere: {center: [x, y, z], max_range: 4.0, min_range: 0.5}}
      validation: 200         # random configurations of the accuracy map
      curve: [10, 20, 30, 45, 60]   # pose counts of the accuracy curve (default: about 8 from the minimum to 2 N)
      output: {dir: robocal-plan}

Written (atomically, into one folder): poses.csv and poses.yaml (the chosen readings, in the data's
joint units), prediction.json, accuracy_map.csv, accuracy_curve.csv, summary.txt.
"""
from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from robocal.workflows.config import data_units, joint_columns, read_checked_config, robot_from_config, setup_from_config
from robocal.workflows.config_keys import Cfg
from robocal.workflows.config_measurements import residual_class
from robocal.workflows.config_sections import is_prismatic
from robocal.io.tables import ANGLE_UNITS, LENGTH_UNITS, Table
from robocal.design.selection import DesignMatrix, PoseSelection, select_poses
from robocal.design.candidates import CandidateFilter, MeasurementVolume, filter_candidates, grid_candidates, \
    random_candidates
from robocal.design.criteria import CRITERIA
from robocal.errors import InputError
from robocal.estimation.parallel_map import map_tasks
from robocal.model.kinematics import ModelState
from robocal.io.output_folder import write_folder
from robocal.model.parameters import ParameterSet
from robocal.design.prediction import (CurvePoint, ParameterPrediction, PosePrediction, accuracy_curve, pose_jacobians,
                         position_weight, predict_parameters, predict_pose_accuracy)



@dataclass
class Plan:
    config: Path
    frame: str
    joint_names: list[str]
    joint_columns: list[str]
    candidates: np.ndarray            # (K, n_joints) kept candidate readings, SI
    screening: CandidateFilter
    design: DesignMatrix
    selection: PoseSelection
    parameters: ParameterPrediction
    validation: np.ndarray            # (V, n_joints)
    validation_xyz: np.ndarray        # (V, 3) frame origin in the measurement frame
    accuracy: PosePrediction
    curve: list[CurvePoint]
    output_dir: Path
    joint_units: dict[str, str]
    prismatic: list[bool]             # per joint: reads metres (else radians)
    param_units: dict[str, str]       # 'm' or 'rad' per parameter name

    @property
    def poses(self) -> np.ndarray:
        return self.candidates[self.selection.labels]


def plan_from_config(path: str | Path, seed: int | None = None, scheduler: str | None = None,
                     workers: int | None = None) -> Plan:
    """The plan of a config; the accuracy curve's points (independent selections, no random draws) are
    computed on Dask when `scheduler` or `workers` is given (docs/fleet.md), identical to the serial run."""
    path = Path(path).resolve()
    raw, root = read_checked_config(path)
    plan = root.child("plan", {})
    plan.require_mapping()
    base_dir = path.parent
    robot = robot_from_config(root.child("robot"), base_dir)
    blocks = root.get("measurements", required=True, types=list)
    frames = [b.get("frame") for b in blocks if isinstance(b, dict)]
    frame = plan.get("frame", frames[0] if frames else None, types=str)
    if frame is None:
        raise plan.error("no frame to predict: give plan.frame or a measurement block with a frame", "frame")
    try:
        robot.frame_id(frame)
    except InputError as exc:
        raise plan.error(exc.reason, "frame") from None
    data = root.child("data", {})
    data.require_mapping()
    joint_cols = joint_columns(data, robot, [f for f in frames if isinstance(f, str)])
    joint_names = list(joint_cols)
    _, joint_units = data_units(data)
    rng = np.random.default_rng(plan.get("seed", 0, types=int) if seed is None else seed)

    # Candidates, screened on the nominal robot.
    cand = plan.child("candidates", {})
    cand.require_mapping()
    method = cand.get("method", "random", types=str)
    margin = float(cand.get("margin", 0.05, types=(int, float)))
    if method == "random":
        proposed = random_candidates(robot, joint_names, cand.get("count", 1000, types=int), rng, margin)
    elif method == "grid":
        try:
            proposed = grid_candidates(robot, joint_names, cand.get("levels", 4, types=(int, list)), margin)
        except InputError as exc:
            raise cand.error(exc.reason, "levels") from None
    else:
        raise cand.error("method must be random or grid", "method")
    volume = MeasurementVolume.from_dict(plan.get("volume"), str(path), "plan.volume")
    nominal = ModelState(robot, ParameterSet(), joint_names)
    screening = filter_candidates(nominal, proposed, frame, volume,
                                  float(cand.get("min_singular", 0.02, types=(int, float))),
                                  float(cand.get("length_scale", 0.5, types=(int, float))))
    if not len(screening.kept):
        raise plan.error(f"all {len(proposed)} candidates were dropped ({screening.dropped})", "candidates")
    candidates = proposed[screening.kept]

    problem = _candidate_problem(raw, root, plan, robot, joint_cols, joint_units, candidates)
    design = DesignMatrix.from_problem(problem)
    candidates = problem.values.copy()      # contact candidates now sit on their (nominal) contact
    validation = random_candidates(robot, joint_names, plan.get("validation", 200, types=int), rng, margin)
    G = pose_jacobians(problem, frame, validation)
    xyz = np.array([nominal.sample(v).pose(frame).translation for v in validation])

    n = plan.get("N", 30, types=int)
    criterion = plan.get("criterion", "D", types=str)
    if criterion not in CRITERIA:
        raise plan.error(f"unknown criterion '{criterion}' (known: {', '.join(CRITERIA)})", "criterion")
    if not 1 <= n <= design.n_candidates:
        raise plan.error(f"cannot choose {n} poses from {design.n_candidates} candidates", "N")
    W = position_weight(G)
    selection = select_poses(design, n, criterion, W=W)
    params = predict_parameters(design, selection.chosen)
    accuracy = predict_pose_accuracy(params, G)
    counts = plan.get("curve", None, types=list) or _default_counts(design, n)
    counts = [int(c) for c in counts if 1 <= int(c) <= design.n_candidates]
    curve_of = functools.partial(accuracy_curve, design, G=G, criterion=criterion, W=W)
    curve = [c for one in map_tasks(curve_of, [[n] for n in counts], scheduler, workers) for c in one]
    out = plan.child("output", {})
    out.require_mapping()
    prismatic = [is_prismatic(robot, j) for j in joint_names]
    return Plan(path, frame, joint_names, list(joint_cols.values()), candidates, screening, design, selection,
                params, validation, xyz, accuracy, curve,
                (base_dir / out.get("dir", "robocal-plan", types=str)).resolve(), joint_units, prismatic,
                {p.name: p.unit for p in problem.params})


def _candidate_problem(raw, root, plan, robot, joint_cols, joint_units, candidates):
    """The calibration problem of the config with one sample per candidate (placeholder measurements),
    read from an in-memory table in the config's joint units."""
    blocks = [Cfg(b, f"measurements[{i}]", root.source) for i, b in enumerate(raw["measurements"])]
    cols = {}
    for k, (j, c) in enumerate(joint_cols.items()):
        kind = "length" if is_prismatic(robot, j) else "angle"
        unit = (LENGTH_UNITS if kind == "length" else ANGLE_UNITS)[joint_units[kind]]
        cols[c] = candidates[:, k] / unit
    for b in blocks:
        b.require_mapping()
        cls = residual_class(b)
        if not cls.observed and len(blocks) > 1:
            # each candidate is moved onto its contact, so a contact block cannot share candidates
            raise b.error("robocal plan takes a contact block (plane, sphere, cylinder, laser line) as the only "
                          "measurement block; plan mixes from Python (robocal.design.selection)", "type")
        names = [str(c) for c in b.get("columns", [], types=list)]
        for c in names:
            cols.setdefault(c, np.zeros(len(candidates)))
        if b.value.get("type") == "pose" and len(names) == 7:
            cols[names[6]] = np.ones(len(candidates))    # qw of an identity placeholder
    table = Table.from_columns(Path(root.source).with_name("plan candidates (in memory)"), cols)
    every_row = [np.arange(len(candidates))] * len(blocks)
    setup = setup_from_config(raw, Path(root.source).parent, root.source, table=table, block_rows=every_row,
                              sigma=plan.get("noise"))
    return setup.problem


def _default_counts(design, n) -> list[int]:
    n_min = int(np.ceil(len(design.base.independent) / max(int(design.rows.max()), 1)))
    hi = min(2 * n, design.n_candidates)
    return sorted({int(c) for c in np.round(np.geomspace(max(n_min, 1), hi, 8))} | {n})


# ---- writing ---------------------------------------------------------------------------------
def plan_files(plan: Plan) -> dict[str, bytes]:
    scale = np.array([1 / LENGTH_UNITS[plan.joint_units["length"]] if pr else 1 / ANGLE_UNITS[plan.joint_units["angle"]]
                      for pr in plan.prismatic])
    poses = plan.poses * scale
    files = {}
    header = ",".join(["pose"] + plan.joint_columns)
    lines = [header] + [",".join([str(i + 1)] + [f"{v:.10g}" for v in row]) for i, row in enumerate(poses)]
    files["poses.csv"] = ("\n".join(lines) + "\n").encode()
    doc = {"units": plan.joint_units, "joints": plan.joint_columns,
           "poses": [{"name": f"pose_{i + 1:03d}", "values": [float(f"{v:.10g}") for v in row]}
                     for i, row in enumerate(poses)]}
    files["poses.yaml"] = yaml.safe_dump(doc, sort_keys=False).encode()
    files["prediction.json"] = (json.dumps(prediction_dict(plan), indent=2) + "\n").encode()
    acc = plan.accuracy
    rows = ["x_m,y_m,z_m,position_rms_mm,sigma_x_mm,sigma_y_mm,sigma_z_mm,orientation_rms_mrad"]
    for p, r, ax, o in zip(plan.validation_xyz, acc.position, acc.position_axes, acc.orientation):
        rows.append(",".join(f"{v:.6g}" for v in (*p, 1e3 * r, *(1e3 * ax), 1e3 * o)))
    files["accuracy_map.csv"] = ("\n".join(rows) + "\n").encode()
    rows = ["n_poses,criterion_value,mean_position_mm,rms_position_mm,max_position_mm,mean_orientation_mrad,"
            "max_orientation_mrad"]
    for c in plan.curve:
        s = c.prediction.summary()
        rows.append(",".join([str(c.n), f"{c.criterion_value:.6g}"] + [f"{s[k]:.6g}" for k in (
            "mean_position_mm", "rms_position_mm", "max_position_mm", "mean_orientation_mrad",
            "max_orientation_mrad")]))
    files["accuracy_curve.csv"] = ("\n".join(rows) + "\n").encode()
    files["summary.txt"] = (summary(plan) + "\n").encode()
    return files


def prediction_dict(plan: Plan) -> dict:
    sel, pp = plan.selection, plan.parameters
    return {
        "config": str(plan.config), "frame": plan.frame, "criterion": sel.criterion, "n_poses": len(sel.chosen),
        "candidates": {"kept": len(plan.candidates), "dropped": plan.screening.dropped},
        "criteria": {k: float(v) for k, v in sel.values.items()},
        "identifiable": sel.identifiability.ok,
        "unidentifiable": sel.identifiability.unidentifiable,
        "unidentifiable_explanation": sel.identifiability.explanation,
        "never_identifiable": pp.structural,
        "parameters": [{"name": n, "stderr": float(s), "unit": plan.param_units.get(n, "")}
                       for n, s in zip(pp.names, pp.stderr)],
        "tool_accuracy": plan.accuracy.summary(),
        "curve": [{"n_poses": c.n, **c.prediction.summary()} for c in plan.curve],
        "units": "SI for parameters; tool accuracy in mm and mrad (1 sigma, RMS over axes)",
    }


def summary(plan: Plan) -> str:
    sel, acc = plan.selection, plan.accuracy.summary()
    lines = [f"robocal plan: {len(sel.chosen)} poses of {len(plan.candidates)} candidates by {sel.criterion}-optimality "
             f"({sel.exchanges} exchanges after the greedy start)",
             "  dropped candidates: " + ", ".join(f"{k} {v}" for k, v in plan.screening.dropped.items()),
             f"  identifiable parameters: {len(plan.parameters.names)}; fixed (never identifiable from these "
             f"measurements): {len(plan.parameters.structural)}"]
    if not sel.identifiability.ok:
        lines.append("  NOT IDENTIFIABLE with this pose set:")
        lines += [f"    {t}" for t in sel.identifiability.explanation]
    else:
        lines.append(f"  predicted {plan.frame} accuracy over {len(plan.validation)} configurations (1 sigma): "
                     f"position mean {acc['mean_position_mm']:.4f} mm, max {acc['max_position_mm']:.4f} mm; "
                     f"orientation mean {acc['mean_orientation_mrad']:.4f} mrad")
        worst = np.argsort(-plan.parameters.stderr)[:5]
        lines.append("  least certain parameters: " + ", ".join(
            f"{plan.parameters.names[i]} {plan.parameters.stderr[i] * 1e3:.3g} "
            f"{'mrad' if plan.param_units.get(plan.parameters.names[i]) == 'rad' else 'mm'}" for i in worst))
    lines.append("  accuracy curve (poses: mean position mm): " + ", ".join(
        f"{c.n}: {c.prediction.summary()['mean_position_mm']:.4g}" for c in plan.curve))
    return "\n".join(lines)


def write_plan(plan: Plan, out_dir: str | Path | None = None, force: bool = False) -> dict[str, Path]:
    """Write every plan file into a temporary folder renamed into place when complete."""
    out = Path(out_dir).resolve() if out_dir else plan.output_dir
    files = plan_files(plan)
    return write_folder(out, files, force)
