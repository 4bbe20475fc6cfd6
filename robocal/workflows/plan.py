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

A camera block plans viewpoints that keep its target in view (plan_camera.py).

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

from robocal.residuals import REGISTRY
from robocal.workflows.config_read import read_config
from robocal.workflows.config_sections import is_prismatic
from robocal.workflows.config_types import CalibrationConfig, PlanConfig
from robocal.workflows.plan_camera import camera_block, camera_plan_problem
from robocal.workflows.setup import build_robot, build_setup, joint_columns
from robocal.io.tables import ANGLE_UNITS, LENGTH_UNITS, Table
from robocal.design.selection import DesignMatrix, PoseSelection, greedy_order, select_poses
from robocal.design.candidates import CandidateFilter, filter_candidates, grid_candidates, \
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
    config = read_config(path)
    plan = config.plan or PlanConfig(output_dir=(config.base_dir / "robocal-plan").resolve())
    robot = build_robot(config.robot, config.source)
    frame = plan.frame or config.measurements[0].frame
    camera = camera_block(config)
    joint_cols = joint_columns(config.data, robot, config.frames, config.source)
    joint_names = list(joint_cols)
    rng = np.random.default_rng(plan.seed if seed is None else seed)
    if camera is not None:         # viewpoints of the target (plan_camera.py); the camera frame added if new
        screening, candidates, problem = camera_plan_problem(config, plan, camera, robot, joint_cols, rng)
    try:
        robot.frame_id(frame)
    except InputError as exc:
        raise InputError(exc.reason, source=config.source, field="plan.frame") from None
    nominal = ModelState(robot, ParameterSet(), joint_names)
    if camera is None:
        screening, candidates = screened_candidates(plan, config.source, robot, nominal, joint_names, frame, rng)
        problem = candidate_problem(config, plan, robot, joint_cols, candidates)
    design = DesignMatrix.from_problem(problem)
    candidates = problem.values.copy()      # contact candidates now sit on their (nominal) contact
    validation = random_candidates(robot, joint_names, plan.validation, rng, plan.candidates.margin)
    G = pose_jacobians(problem, frame, validation)
    xyz = np.array([nominal.sample(v).pose(frame).translation for v in validation])
    if plan.criterion not in CRITERIA:
        raise InputError(f"unknown criterion '{plan.criterion}' (known: {', '.join(CRITERIA)})", source=config.source,
                         field="plan.criterion")
    if not 1 <= plan.n <= design.n_candidates:
        raise InputError(f"cannot choose {plan.n} poses from {design.n_candidates} candidates", source=config.source,
                         field="plan.N")
    W = position_weight(G)
    counts = [int(c) for c in plan.curve or _default_counts(design, plan.n) if 1 <= int(c) <= design.n_candidates]
    greedy = greedy_order(design, max([plan.n, *counts]), plan.criterion, W)     # one greedy run for every count
    selection = select_poses(design, plan.n, plan.criterion, W=W, start=greedy[:plan.n])
    params = predict_parameters(design, selection.chosen)
    accuracy = predict_pose_accuracy(params, G)
    curve_of = functools.partial(accuracy_curve, design, G=G, criterion=plan.criterion, W=W, greedy=greedy)
    others = [n for n in counts if n != plan.n]          # the plan's own count is the selection above
    done = {c.n: c for one in map_tasks(curve_of, [[n] for n in others], scheduler, workers) for c in one}
    done[plan.n] = CurvePoint(plan.n, selection.value, accuracy)
    curve = [done[n] for n in counts]
    prismatic = [is_prismatic(robot, j) for j in joint_names]
    return Plan(Path(config.source), frame, joint_names, list(joint_cols.values()), candidates, screening, design,
                selection, params, validation, xyz, accuracy, curve, plan.output_dir,
                config.data.joint_units.as_dict(), prismatic, {p.name: p.unit for p in problem.params})


def screened_candidates(plan: PlanConfig, source: str, robot, nominal, joint_names, frame, rng):
    """(the screening, the kept candidate readings): drawn at random or on a grid, screened on the nominal robot."""
    cand = plan.candidates
    if cand.method == "random":
        proposed = random_candidates(robot, joint_names, cand.count, rng, cand.margin)
    else:
        try:
            proposed = grid_candidates(robot, joint_names, cand.levels if isinstance(cand.levels, int)
                                       else list(cand.levels), cand.margin)
        except InputError as exc:
            raise InputError(exc.reason, source=source, field="plan.candidates.levels") from None
    screening = filter_candidates(nominal, proposed, frame, plan.volume, cand.min_singular, cand.length_scale)
    if not len(screening.kept):
        raise InputError(f"all {len(proposed)} candidates were dropped ({screening.dropped})", source=source,
                         field="plan.candidates")
    return screening, proposed[screening.kept]


def candidate_problem(config: CalibrationConfig, plan: PlanConfig, robot, joint_cols, candidates):
    """The calibration problem of the config with one sample per candidate (placeholder measurements),
    read from an in-memory table in the config's joint units."""
    cols = {}
    joint_units = config.data.joint_units
    for k, (j, c) in enumerate(joint_cols.items()):
        kind = "length" if is_prismatic(robot, j) else "angle"
        unit = (LENGTH_UNITS if kind == "length" else ANGLE_UNITS)[getattr(joint_units, kind)]
        cols[c] = candidates[:, k] / unit
    for m in config.measurements:
        if not REGISTRY[m.type].observed and len(config.measurements) > 1:
            # each candidate is moved onto its contact, so a contact block cannot share candidates
            raise InputError("robocal plan takes a contact block (plane, sphere, cylinder, laser line) as the only "
                             "measurement block; plan mixes from Python (robocal.design.selection)",
                             source=config.source, field=f"{m.path}.type")
        for c in m.columns:
            cols.setdefault(c, np.zeros(len(candidates)))
        if m.type == "pose" and len(m.columns) == 7:
            cols[m.columns[6]] = np.ones(len(candidates))    # qw of an identity placeholder
    table = Table.from_columns(Path(config.source).with_name("plan candidates (in memory)"), cols)
    every_row = [np.arange(len(candidates))] * len(config.measurements)
    return build_setup(config, table=table, block_rows=every_row, sigma=plan.noise).problem


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
        names, se = plan.parameters.names, plan.parameters.stderr
        geometric = [i for i, n in enumerate(names) if plan.param_units.get(n) in ("m", "rad")]
        worst = sorted(geometric, key=lambda i: -se[i])[:5]
        lines.append("  least certain parameters: " + ", ".join(
            f"{names[i]} {se[i] * 1e3:.3g} {'mrad' if plan.param_units.get(names[i]) == 'rad' else 'mm'}"
            for i in worst))
        other = [i for i in range(len(names)) if i not in geometric]
        if other:         # a camera's intrinsics: px and unitless distortion terms
            lines.append("  camera intrinsics: " + ", ".join(
                f"{names[i]} {se[i]:.3g}{' ' + plan.param_units[names[i]] if plan.param_units.get(names[i]) else ''}"
                for i in other))
    lines.append("  accuracy curve (poses: mean position mm): " + ", ".join(
        f"{c.n}: {c.prediction.summary()['mean_position_mm']:.4g}" for c in plan.curve))
    return "\n".join(lines)


def write_plan(plan: Plan, out_dir: str | Path | None = None, force: bool = False) -> dict[str, Path]:
    """Write every plan file into a temporary folder renamed into place when complete."""
    out = Path(out_dir).resolve() if out_dir else plan.output_dir
    files = plan_files(plan)
    return write_folder(out, files, force)
