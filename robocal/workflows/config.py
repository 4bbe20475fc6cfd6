"""The calibration YAML: robot, data, parameters, measurements, solver, output (docs/config.md).

`setup_from_config(raw, base_dir, source)` is the one path from a parsed config to a `Setup` (robot,
problem, options); `load_config(path)` reads the file first. Every command uses it: calibrate,
simulate and plan (which pass an in-memory table instead of the data file), iso9283, evaluate and the
testing helpers. Every mistake names the file and the key path (`measurements[1].frame`).
Units: see docs/config.md, "Units" (measurement columns and their sigmas in `data.units`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.io.yaml_files import read_yaml
from robocal.estimation.calibrate import CalibrationOptions
from robocal.estimation.problem import Problem
from robocal.workflows.config_keys import TOP_KEYS, Cfg, check_keys
from robocal.workflows.config_measurements import residual_class, residual_from_block
from robocal.workflows.config_sections import (apply_parameter_overrides, approach_directions, joint_values,
                                        parameters_from_config, solver_options)
from robocal.io.tables import ANGLE_UNITS, LENGTH_UNITS, Table, read_csv
from robocal.model.mjcf import load_mjcf
from robocal.model.robot import Robot, load_example, load_urdf

__all__ = ["Setup", "Cfg", "TOP_KEYS", "load_config", "read_yaml", "read_checked_config", "setup_from_config", "robot_from_config",
           "default_joints", "data_units"]


@dataclass
class Setup:
    robot: Robot
    problem: Problem
    options: CalibrationOptions
    output_dir: Path
    config_path: Path
    tables: dict[str, Table] = field(default_factory=dict)
    raw: dict = field(default_factory=dict)
    sample_rows: list[tuple[str, int]] = field(default_factory=list)   # (file, data row) of each sample
    joint_columns: dict[str, str] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=lambda: {"length": "m", "angle": "rad"})
    joint_units: dict[str, str] = field(default_factory=lambda: {"length": "m", "angle": "rad"})
    source: str = ""


def read_checked_config(path: Path) -> tuple[dict, Cfg]:
    """A config file parsed and checked key by key at every level: (the mapping, its root Cfg)."""
    raw = read_yaml(path)
    if not isinstance(raw, dict):
        raise InputError("the config is empty or not a mapping of sections", source=str(path))
    check_keys(raw, str(path))
    return raw, Cfg(raw, "", str(path))


def load_config(path: str | Path, urdf: str | Path | None = None) -> Setup:
    """The Setup of a calibration YAML file (see setup_from_config), with the robot taken from `urdf`
    instead of the config's when given (a unit's own URDF, a model under test)."""
    path = Path(path).resolve()
    raw = read_yaml(path)
    if urdf is not None and isinstance(raw, dict):
        robot_cfg = {k: v for k, v in (raw.get("robot") or {}).items()
                     if k not in ("urdf", "example", "mjcf", "actuated")}
        raw = {**raw, "robot": {**robot_cfg, "urdf": str(Path(urdf).resolve())}}
    return setup_from_config(raw, path.parent, str(path))


def data_units(data: Cfg) -> tuple[dict[str, str], dict[str, str]]:
    """(units of measurement columns, units of joint columns) of the `data:` section, checked."""
    out = []
    for key in ("units", "joint_units"):
        node = data.child(key, {})
        node.require_mapping()
        units = {"length": node.get("length", "m", types=str), "angle": node.get("angle", "rad", types=str)}
        for kind, allowed in (("length", LENGTH_UNITS), ("angle", ANGLE_UNITS)):
            if units[kind] not in allowed:
                raise node.error(f"unknown unit '{units[kind]}' (allowed: {', '.join(allowed)})", kind)
        out.append(units)
    return out[0], out[1]


def default_joints(robot: Robot, frames: Sequence[str]) -> list[str]:
    """The joints read by default: every joint that moves one of the measured frames, in model order; for a
    closed chain the actuated joints (the others follow from the closures)."""
    if robot.loops is not None:
        return list(robot.loops.actuated)
    return [j for j in robot.joint_names if any(j in robot.supporting_joints(f) for f in frames)]


def setup_from_config(raw, base_dir: str | Path, source: str, *, table: Table | None = None,
                      block_rows: Sequence[np.ndarray] | None = None, sigma=None) -> Setup:
    """The Setup of a parsed config (a dict, paths relative to base_dir; source names it in errors).

    table       read every measurement block from this table (in the config's units) instead of the
                data files: `robocal simulate`, `robocal plan`, a validation file
    block_rows  the rows of `table` each block uses (instead of its `where`)
    sigma       replaces every block's sigma (robocal plan's `noise`), in data units
    Sections the setup does not use (simulation, plan, iso9283) are checked for misspelt keys only.
    """
    base_dir = Path(base_dir)
    root = Cfg(raw, "", source)
    if not isinstance(raw, dict):
        raise InputError("the config is empty or not a mapping of sections "
                         f"({', '.join(TOP_KEYS)})", source=source)
    check_keys(raw, source)
    robot = robot_from_config(root.child("robot"), base_dir)
    data = root.child("data", {})
    data.require_mapping()
    units, joint_units = data_units(data)
    tables: dict[str, Table] = {}
    if table is not None:
        tables[str(table.path)] = table

    def table_of(block: Cfg) -> Table:
        if table is not None:
            return table
        owner, key = (block, "csv") if "csv" in block.value else (data, "csv")
        p = (base_dir / owner.get(key, required=True, types=str)).resolve()
        if not p.is_file():
            raise owner.error(f"data file not found: {p}", key)
        if str(p) not in tables:
            tables[str(p)] = read_csv(p)
        return tables[str(p)]

    meas = root.child("measurements")
    if not isinstance(meas.value, list) or not meas.value:
        raise meas.error("need a list of at least one measurement block")
    blocks = [Cfg(m, f"measurements[{i}]", source) for i, m in enumerate(meas.value)]
    classes, frames = [], []
    for b in blocks:
        b.require_mapping()
        classes.append(residual_class(b))
        frames.append(b.get("frame", required=True, types=str))
        try:
            robot.frame_id(frames[-1])
        except InputError as exc:
            raise b.error(exc.reason, "frame") from None
    joint_cols = joint_columns(data, robot, frames)

    samples: dict[tuple[str, int], int] = {}
    values: list[np.ndarray] = []
    residuals = []
    for i, (b, cls) in enumerate(zip(blocks, classes)):
        tab = table_of(b)
        rows = _block_rows(b, tab, None if block_rows is None else block_rows[i], data)
        sample_idx = []
        for r, v in zip(rows, joint_values(robot, tab, joint_cols, rows, joint_units)):
            key = (str(tab.path), int(r))
            if key not in samples:
                samples[key] = len(values)
                values.append(v)
            sample_idx.append(samples[key])
        residuals.append(residual_from_block(cls, b, tab, rows, np.array(sample_idx), units, sigma))
    pcfg = root.child("parameters")
    params = parameters_from_config(pcfg, robot, [j for j in joint_cols if j in default_joints(robot, frames)])
    directions = approach_directions(data.child("approach"), pcfg, params, robot, tables, samples, joint_cols,
                                     joint_units)
    problem = Problem(robot, params, list(joint_cols), np.array(values), residuals, directions)
    apply_parameter_overrides(pcfg, params)
    options = solver_options(root.child("solver"))
    out = root.child("output", {})
    out.require_mapping()
    output_dir = (base_dir / out.get("dir", "robocal-output", types=str)).resolve()
    return Setup(robot, problem, options, output_dir, base_dir, tables, raw, list(samples), joint_cols, units,
                 joint_units, source)


def _block_rows(block: Cfg, tab: Table, given, data: Cfg) -> np.ndarray:
    """The table rows a block reads: given, its `where` selection, or every row."""
    if given is not None:
        return np.asarray(given, dtype=int)
    where = block.get("where", types=dict)
    if where:
        if len(where) != 1:
            raise block.error("where selects rows by one column: {column: value}", "where")
        (col, val), = where.items()
        try:
            rows = tab.rows_where(str(col), val)
        except InputError as exc:
            raise InputError(exc.reason, source=exc.source, field=f"{block.where('where')}.{col}") from None
    else:
        rows = np.arange(tab.n_rows)
    if not len(rows):
        key = block.where("where") if where else (block.where("csv") if "csv" in block.value else "data.csv")
        raise InputError(f"no data rows in {tab.path}" + (f" where {where}" if where else ""), source=data.source,
                         field=key)
    return rows


def joint_columns(data: Cfg, robot: Robot, frames: Sequence[str]) -> dict[str, str]:
    """{joint: CSV column} of `data.joints` (default: every joint moving a measured frame, same names)."""
    joint_cfg = data.get("joints")
    if joint_cfg is None:
        cols = {j: j for j in default_joints(robot, frames)}
    elif isinstance(joint_cfg, list):
        cols = {str(j): str(j) for j in joint_cfg}
    elif isinstance(joint_cfg, dict):
        cols = {str(k): str(v) for k, v in joint_cfg.items()}
    else:
        raise data.error("expected a list of joint names or a mapping joint -> column", "joints")
    for j in cols:
        try:
            robot.joint_id(j)
        except InputError as exc:
            raise data.error(exc.reason, "joints") from None
    needed = set(default_joints(robot, frames))
    missing = [j for j in robot.joint_names if j in needed and j not in cols]
    if missing:
        raise data.error(f"joints {', '.join(missing)} move the measured frames but have no column", "joints")
    return cols


def robot_from_config(cfg: Cfg, base_dir: Path) -> Robot:
    """The robot of the `robot:` section, with its base placement and added frames."""
    if cfg.value is None:
        raise cfg.error("required section is missing (give robot.urdf, robot.mjcf or robot.example)")
    cfg.require_mapping()
    if sum(key in cfg.value for key in ("urdf", "example", "mjcf")) != 1:
        raise cfg.error("give exactly one of 'urdf' (a file), 'mjcf' (a file) or 'example' (a robot name)")
    if "actuated" in cfg.value and "mjcf" not in cfg.value:
        raise cfg.error("'actuated' goes with 'mjcf' (a URDF names its actuated joints in <actuated>)", "actuated")
    if "mjcf" in cfg.value:
        actuated = cfg.get("actuated", types=list)
        robot = load_mjcf(base_dir / cfg.get("mjcf", types=str),
                          actuated=None if actuated is None else [str(j) for j in actuated])
    elif "urdf" in cfg.value:
        dirs = [str((base_dir / str(d)).resolve()) for d in cfg.get("package_dirs", [], types=list)]
        robot = load_urdf(base_dir / cfg.get("urdf", types=str), package_dirs=dirs)
    else:
        try:
            robot = load_example(cfg.get("example", types=str))
        except InputError as exc:
            raise cfg.error(exc.reason, "example") from None
    robot.base_placement = _placement(cfg.child("base"))
    for i, f in enumerate(cfg.get("frames", [], types=list)):
        fc = Cfg(f, f"{cfg.path}.frames[{i}]", cfg.source)
        fc.require_mapping()
        try:
            robot.add_frame(fc.get("name", required=True, types=str), fc.get("parent", required=True, types=str),
                            _placement(fc))
        except InputError as exc:
            if exc.field and exc.source == cfg.source:
                raise
            raise fc.error(exc.reason) from None
    return robot


def _placement(cfg: Cfg) -> pin.SE3:
    """xyz (m) and rpy (rad) of a mapping, as an SE3 (identity when absent)."""
    if cfg.value is None:
        return pin.SE3.Identity()
    cfg.require_mapping()
    out = []
    for key in ("xyz", "rpy"):
        v = cfg.get(key, [0, 0, 0], types=list)
        if len(v) != 3 or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)
                                  for x in v):
            raise cfg.error(f"expected three finite numbers, got {v!r}", key)
        out.append(np.asarray(v, dtype=float))
    return pin.SE3(pin.rpy.rpyToMatrix(*out[1]), out[0])
