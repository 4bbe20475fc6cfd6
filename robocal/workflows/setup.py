"""A checked config -> the set-up of a calibration: the robot, its data and the problem to fit.

`build_setup(config)` is the one path from a typed config (config_read.py) to a `Setup` (robot, problem,
options); `load_config(path)` reads the file first. Every workflow uses it: calibrate, select, evaluate,
cv, iso9283, the fleet's units, and simulate and plan (which pass an in-memory table instead of the data
file). Checks that need the robot or the data (frame and joint names, columns, units) are made here, and
every mistake names the file and the key path (`measurements[1].frame`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.estimation.calibrate import CalibrationOptions
from robocal.estimation.problem import Problem
from robocal.estimation.sessions import Sessions
from robocal.io.tables import Table, read_csv
from robocal.model.mjcf import load_mjcf
from robocal.model.robot import Robot, load_example, load_urdf
from robocal.residuals import REGISTRY
from robocal.estimation.camera_block import CameraSetup
from robocal.workflows.config_camera import block_frame_exists, camera_residual, image_labels
from robocal.workflows.config_measurements import residual_from_block
from robocal.workflows.config_read import parse_config, read_config
from robocal.workflows.config_sections import (apply_parameter_overrides, approach_directions, joint_values,
                                               parameter_set)
from robocal.workflows.config_types import CalibrationConfig, DataConfig, MeasurementConfig, Placement, RobotConfig
from robocal.workflows.reading_check import check_joint_columns


@dataclass
class Setup:
    """What a calibration works on: the robot, the problem (samples, residuals, parameters), the solver
    options, the output folder, the typed config it came from, and where each sample's row came from."""

    robot: Robot
    problem: Problem
    options: CalibrationOptions
    output_dir: Path
    config: CalibrationConfig
    tables: dict[str, Table] = field(default_factory=dict)
    sample_rows: list[tuple[str, int]] = field(default_factory=list)   # (file, data row) of each sample
    joint_columns: dict[str, str] = field(default_factory=dict)
    cameras: dict[str, CameraSetup] = field(default_factory=dict)      # camera blocks' set-ups, by block name

    @property
    def source(self) -> str:
        return self.config.source

    @property
    def units(self) -> dict[str, str]:
        return self.config.data.units.as_dict()

    @property
    def joint_units(self) -> dict[str, str]:
        return self.config.data.joint_units.as_dict()


def load_config(path: str | Path, urdf: str | Path | None = None) -> Setup:
    """The Setup of a calibration YAML file, with the robot taken from `urdf` instead of the config's when
    given (a unit's own URDF, a model under test)."""
    config = read_config(path)
    if urdf is not None:
        config = with_urdf(config, urdf)
    return build_setup(config)


def with_urdf(config: CalibrationConfig, urdf: str | Path) -> CalibrationConfig:
    """The config with its robot read from another URDF file (base placement and added frames kept)."""
    robot = dataclasses.replace(config.robot, urdf=Path(urdf).resolve(), example=None, mjcf=None, actuated=None)
    return dataclasses.replace(config, robot=robot)


def setup_from_config(raw, base_dir: str | Path, source: str, **kwargs) -> Setup:
    """The Setup of a parsed YAML mapping (paths relative to base_dir): parse_config, then build_setup."""
    return build_setup(parse_config(raw, base_dir, source), **kwargs)


def default_joints(robot: Robot, frames: Sequence[str]) -> list[str]:
    """The joints read by default: every joint that moves one of the measured frames, in model order; for a
    closed chain the actuated joints (the others follow from the closures)."""
    if robot.loops is not None:
        return list(robot.loops.actuated)
    return [j for j in robot.joint_names if any(j in robot.supporting_joints(f) for f in frames)]


def build_setup(config: CalibrationConfig, *, table: Table | None = None,
                block_rows: Sequence[np.ndarray] | None = None, sigma=None, camera_cache: dict | None = None) -> Setup:
    """The Setup of a checked config.

    table       read every measurement block from this table (in the config's units) instead of the
                data files: `robocal simulate`, `robocal plan`, a validation file
    block_rows  the rows of `table` each block uses (instead of its `where`)
    sigma       replaces every block's sigma (robocal plan's `noise`), in data units
    camera_cache  a dict shared by set-ups of the same images: each camera image's PnP and the hand-eye
                  solved once (camera_block.solved_once)
    """
    source, data = config.source, config.data
    robot = build_robot(config.robot, source)
    for m in config.measurements:
        if m.camera is not None and not robot.model.existFrame(m.frame):
            block_frame_exists(robot, m)       # the camera set-up adds the frame on attached_to
            continue
        try:
            robot.frame_id(m.frame)
        except InputError as exc:
            raise InputError(exc.reason, source=source, field=f"{m.path}.frame") from None
    joint_cols = joint_columns(data, robot, config.frames, source)
    tables: dict[str, Table] = {} if table is None else {str(table.path): table}
    samples: dict[tuple[str, int], int] = {}
    values: list[np.ndarray] = []
    session_of: list[int] = []
    names: list[str] = [s.name for s in data.sessions] if table is None else []
    residuals, cameras = [], {}
    for i, m in enumerate(config.measurements):
        idx, rows_all, labels_of = [], [], []
        for s, tab in block_tables(m, data, table, tables, source):
            rows = block_table_rows(m, tab, None if block_rows is None else block_rows[i], source)
            labels = session_labels(tab, rows, data.session_column) if data.session_column and table is None else None
            for n, (r, v) in enumerate(zip(rows, joint_values(robot, tab, joint_cols, rows, data.joint_units))):
                key = (str(tab.path), int(r))
                if key not in samples:
                    samples[key] = len(values)
                    values.append(v)
                    if labels is not None and labels[n] not in names:
                        names.append(labels[n])
                    session_of.append(s if labels is None else names.index(labels[n]))
                idx.append(samples[key])
            rows_all.append((tab, rows))
            labels_of += image_labels(tab, rows) if m.camera is not None else []
        if m.camera is not None:
            several = data.sessions or data.session_column
            cameras[m.name] = camera_residual(robot, m, source, list(joint_cols), np.array([values[k] for k in idx]),
                                              labels_of, idx, np.array([session_of[k] for k in idx]) if several
                                              else None, camera_cache)
            residuals.append(cameras[m.name].residual)
            continue
        residuals.append(residual_from_block(REGISTRY[m.type], m, source, rows_all, np.array(idx), data.units,
                                             sigma))
    chain = [j for j in joint_cols if j in default_joints(robot, config.frames)]
    # a camera block's frame placement is free (its hand-eye), unless the parameters section says otherwise
    pc = dataclasses.replace(config.parameters, frames={**{c.frame: True for c in cameras.values()},
                                                        **config.parameters.frames})
    params = parameter_set(pc, robot, chain, source, list(joint_cols))
    for c in cameras.values():
        params.set_values({n: v for n, v in c.start.items() if n in params})    # the closed form's placement
    directions = approach_directions(data.approach, params, robot, tables, samples, joint_cols, data.joint_units,
                                     source)
    sessions = (Sessions(tuple(names), np.array(session_of), config.parameters.per_session) if len(names) > 1
                else None)
    problem = Problem(robot, params, list(joint_cols), np.array(values), residuals, directions, sessions)
    apply_parameter_overrides(config.parameters, params, source)
    return Setup(robot, problem, dataclasses.replace(config.solver), config.output.dir, config, tables,
                 list(samples), joint_cols, cameras)


def block_tables(m: MeasurementConfig, data: DataConfig, table: Table | None, tables: dict[str, Table],
                 source: str) -> list[tuple[int, Table]]:
    """(session index, table) of every table a block reads: the given table; each session's CSV; or its own
    csv / data.csv (session 0; a session column may split it later)."""
    if table is not None:
        return [(0, table)]
    if data.sessions:
        if m.csv is not None:
            raise InputError("with data.sessions every block reads the sessions' CSV files: remove the block's own "
                             "csv (or give one session's rows through `where`)", source=source, field=f"{m.path}.csv")
        return [(s, read_table(spec.csv, tables, source, f"data.sessions[{s}].csv"))
                for s, spec in enumerate(data.sessions)]
    return [(0, table_of(m, data, tables, source))]


def read_table(path: Path, tables: dict[str, Table], source: str, key: str) -> Table:
    if not path.is_file():
        raise InputError(f"data file not found: {path}", source=source, field=key)
    if str(path) not in tables:
        tables[str(path)] = read_csv(path)
    return tables[str(path)]


def session_labels(tab: Table, rows, column: str) -> list[str]:
    """The session named in `column` for each row (data.session_column)."""
    if not tab.has(column):
        raise InputError(f"no session column '{column}' (columns present: {', '.join(tab.header)})",
                         source=str(tab.path), field=column)
    k = tab.header.index(column)
    labels = [tab.cells[int(r)][k].strip() for r in rows]
    empty = [int(r) for r, lab in zip(rows, labels) if not lab]
    if empty:
        raise InputError("empty session label", source=str(tab.path), row=tab.line(empty[0]), field=column)
    return labels


def table_of(m: MeasurementConfig, data: DataConfig, tables: dict[str, Table], source: str) -> Table:
    """The table a block reads: its own csv, else data.csv (read once)."""
    path, key = (m.csv, f"{m.path}.csv") if m.csv is not None else (data.csv, "data.csv")
    if path is None:
        raise InputError("required key is missing", source=source, field=key)
    if not path.is_file():
        raise InputError(f"data file not found: {path}", source=source, field=key)
    if str(path) not in tables:
        tables[str(path)] = read_csv(path)
    return tables[str(path)]


def block_table_rows(m: MeasurementConfig, tab: Table, given, source: str) -> np.ndarray:
    """The table rows a block reads: given, its `where` selection, or every row."""
    if given is not None:
        return np.asarray(given, dtype=int)
    if m.where is not None:
        col, val = m.where
        try:
            rows = tab.rows_where(str(col), val)
        except InputError as exc:
            raise InputError(exc.reason, source=exc.source, field=f"{m.path}.where.{col}") from None
    else:
        rows = np.arange(tab.n_rows)
    if not len(rows):
        key = f"{m.path}.where" if m.where else (f"{m.path}.csv" if m.csv is not None else "data.csv")
        raise InputError(f"no data rows in {tab.path}" + (f" where {dict([m.where])}" if m.where else ""),
                         source=source, field=key)
    return rows


def joint_columns(data: DataConfig, robot: Robot, frames: Sequence[str], source: str) -> dict[str, str]:
    """{joint: CSV column} of `data.joints` (default: every joint moving a measured frame, same names)."""
    cols = {j: j for j in default_joints(robot, frames)} if data.joints is None else dict(data.joints)
    check_joint_columns(cols, source)
    for j in cols:
        try:
            robot.joint_id(j)
        except InputError as exc:
            raise InputError(exc.reason, source=source, field="data.joints") from None
    needed = set(default_joints(robot, frames))
    missing = [j for j in robot.joint_names if j in needed and j not in cols]
    if missing:
        raise InputError(f"joints {', '.join(missing)} move the measured frames but have no column", source=source,
                         field="data.joints")
    return cols


def build_robot(rc: RobotConfig, source: str) -> Robot:
    """The robot of the `robot:` section, with its base placement and added frames."""
    if rc.mjcf is not None:
        robot = load_mjcf(rc.mjcf, actuated=None if rc.actuated is None else list(rc.actuated))
    elif rc.urdf is not None:
        robot = load_urdf(rc.urdf, package_dirs=[str(d) for d in rc.package_dirs])
    else:
        try:
            robot = load_example(rc.example)
        except InputError as exc:
            raise InputError(exc.reason, source=source, field="robot.example") from None
    robot.base_placement = se3(rc.base)
    for i, f in enumerate(rc.frames):
        try:
            robot.add_frame(f.name, f.parent, se3(f.placement))
        except InputError as exc:
            if exc.field and exc.source == source:
                raise
            raise InputError(exc.reason, source=source, field=f"robot.frames[{i}]") from None
    return robot


def se3(p: Placement) -> pin.SE3:
    return pin.SE3(pin.rpy.rpyToMatrix(*np.asarray(p.rpy, float)), np.asarray(p.xyz, float))
