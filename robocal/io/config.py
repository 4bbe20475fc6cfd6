"""The calibration YAML: robot, data, parameters, measurements, solver, output.

Parsing only: this module turns a config file into a `Setup` (robot, problem, options) and reports
every mistake with the file and the key path (`measurements[1].frame`). Values are SI (m, rad)
unless a key says otherwise; data files may declare mm / deg. See docs/config.md.
"""
from __future__ import annotations

import difflib
import inspect
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

from robocal.model.approach import ApproachSpec, table_directions
from robocal.estimation.calibrate import CalibrationOptions
from robocal.io.tables import ANGLE_UNITS, LENGTH_UNITS, Table, read_csv
from robocal.errors import InputError
from robocal.model.parameters import ParameterSet, robot_parameters
from robocal.estimation.problem import Problem
from robocal.residuals import REGISTRY
from robocal.model.robot import Robot, load_example, load_urdf

TOP_KEYS = ("robot", "data", "parameters", "measurements", "solver", "output", "simulation", "iso9283", "plan")


class Cfg:
    """A mapping from the YAML with its key path, for error messages that say where."""

    def __init__(self, value, path: str, source: str):
        self.value, self.path, self.source = value, path, source

    def error(self, msg: str, key: str | None = None) -> InputError:
        where = f"{self.path}.{key}" if key and self.path else (key or self.path)
        return InputError(msg, source=self.source, field=where or None)

    def require_mapping(self) -> "Cfg":
        if not isinstance(self.value, dict):
            raise self.error(f"expected a mapping, got {type(self.value).__name__}")
        return self

    def check_keys(self, allowed) -> None:
        self.require_mapping()
        for k in self.value:
            if k not in allowed:
                close = difflib.get_close_matches(str(k), list(allowed), n=1)
                hint = f" (did you mean '{close[0]}'?)" if close else f" (allowed: {', '.join(allowed)})"
                raise self.error(f"unknown key{hint}", str(k))

    def get(self, key: str, default=None, required: bool = False, types=None):
        self.require_mapping()
        if key not in self.value:
            if required:
                raise self.error("required key is missing", key)
            return default
        v = self.value[key]
        if types is not None and not isinstance(v, types):
            names = types.__name__ if isinstance(types, type) else "/".join(t.__name__ for t in types)
            raise self.error(f"expected {names}, got {type(v).__name__} ({v!r})", key)
        return v

    def child(self, key: str, default=None) -> "Cfg":
        return Cfg(self.value.get(key, default) if isinstance(self.value, dict) else default,
                   f"{self.path}.{key}" if self.path else key, self.source)


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


def _se3(cfg: Cfg) -> pin.SE3:
    if cfg.value is None:
        return pin.SE3.Identity()
    cfg.check_keys(("xyz", "rpy", "parent", "name"))
    xyz = np.asarray(cfg.get("xyz", [0, 0, 0], types=list), dtype=float)
    rpy = np.asarray(cfg.get("rpy", [0, 0, 0], types=list), dtype=float)
    if xyz.shape != (3,) or rpy.shape != (3,):
        raise cfg.error("xyz and rpy need three numbers each")
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), xyz)


def read_yaml(path: Path):
    """The parsed YAML file, or an InputError naming the file and line."""
    if not path.is_file():
        raise InputError("config file not found", source=str(path))
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        line = getattr(getattr(exc, "problem_mark", None), "line", None)
        raise InputError(f"not valid YAML: {exc}", source=str(path), row=None if line is None else line + 1) from exc


def load_config(path: str | Path) -> Setup:
    path = Path(path).resolve()
    raw = read_yaml(path)
    root = Cfg(raw, "", str(path))
    root.check_keys(TOP_KEYS)
    return build_setup(root, path.parent, raw)


def build_setup(root: Cfg, base_dir: Path, raw: dict) -> Setup:
    robot = _robot(root.child("robot"), base_dir)
    data = root.child("data")
    data.check_keys(("csv", "joints", "units", "joint_units", "approach"))
    tables: dict[str, Table] = {}

    def table(name: str | None, where: Cfg) -> Table:
        name = name or data.get("csv", required=True, types=str)
        p = (base_dir / name).resolve()
        if str(p) not in tables:
            tables[str(p)] = read_csv(p)
        return tables[str(p)]

    units = data.child("units", {})
    units.check_keys(("length", "angle"))
    jn = data.child("joint_units", {})
    jn.check_keys(("length", "angle"))
    length_unit, angle_unit = units.get("length", "m"), units.get("angle", "rad")
    for u, allowed, c, k in ((length_unit, LENGTH_UNITS, units, "length"), (angle_unit, ANGLE_UNITS, units, "angle"),
                             (jn.get("length", "m"), LENGTH_UNITS, jn, "length"),
                             (jn.get("angle", "rad"), ANGLE_UNITS, jn, "angle")):
        if u not in allowed:
            raise c.error(f"unknown unit '{u}' (allowed: {', '.join(allowed)})", k)

    meas = root.child("measurements")
    if not isinstance(meas.value, list) or not meas.value:
        raise meas.error("need a list of at least one measurement block")
    specs = [Cfg(m, f"measurements[{i}]", root.source) for i, m in enumerate(meas.value)]
    frames = []
    for s in specs:
        s.require_mapping()
        frames.append(s.get("frame", required=True, types=str))
        try:
            robot.frame_id(frames[-1])
        except InputError as exc:
            raise s.error(exc.reason, "frame") from None

    joint_cfg = data.get("joints")
    if joint_cfg is None:
        joints = [j for j in robot.joint_names if any(j in robot.supporting_joints(f) for f in frames)]
        joint_cols = {j: j for j in joints}
    elif isinstance(joint_cfg, list):
        joint_cols = {str(j): str(j) for j in joint_cfg}
    elif isinstance(joint_cfg, dict):
        joint_cols = {str(k): str(v) for k, v in joint_cfg.items()}
    else:
        raise data.error("expected a list of joint names or a mapping joint -> column", "joints")
    for j in joint_cols:
        try:
            robot.joint_id(j)
        except InputError as exc:
            raise data.error(exc.reason, "joints") from None
    joint_names = list(joint_cols)
    needed = {j for f in frames for j in robot.supporting_joints(f)}
    missing = [j for j in robot.joint_names if j in needed and j not in joint_cols]
    if missing:
        raise data.error(f"joints {', '.join(missing)} move the measured frames but have no column", "joints")

    samples: dict[tuple[str, int], int] = {}
    values: list[np.ndarray] = []
    residuals = []
    for s in specs:
        res_type = s.get("type", required=True, types=str)
        if res_type not in REGISTRY:
            raise s.error(f"unknown measurement type '{res_type}' (known: {', '.join(sorted(REGISTRY))})", "type")
        cls = REGISTRY[res_type]
        tab = table(s.get("csv", types=str), s)
        where = s.get("where", types=dict)
        if where:
            (col, val), = where.items()
            rows = tab.rows_where(col, val)
        else:
            rows = np.arange(tab.n_rows)
        if not len(rows):
            raise s.error(f"no data rows in {tab.path}", "where" if where else "csv")
        sample_idx = []
        joint_vals = _joint_values(robot, tab, joint_cols, rows, jn)
        for r, v in zip(rows, joint_vals):
            key = (str(tab.path), int(r))
            if key not in samples:
                samples[key] = len(values)
                values.append(v)
            sample_idx.append(samples[key])
        residuals.append(_residual(cls, s, tab, rows, np.array(sample_idx), length_unit, angle_unit))
    params = _parameters(root.child("parameters"), robot, joint_names, frames)
    directions = _directions(data.child("approach"), root.child("parameters"), params, robot, tables, samples,
                             joint_cols, jn)
    problem = Problem(robot, params, joint_names, np.array(values), residuals, directions)
    _parameter_overrides(root.child("parameters"), params)
    options = _solver(root.child("solver"))
    out = root.child("output", {})
    out.check_keys(("dir", "report"))
    output_dir = (base_dir / out.get("dir", "robocal-output", types=str)).resolve()
    return Setup(robot, problem, options, output_dir, base_dir, tables, raw or {}, list(samples), joint_cols)


def _robot(cfg: Cfg, base_dir: Path) -> Robot:
    cfg.require_mapping()
    cfg.check_keys(("urdf", "example", "package_dirs", "base", "frames"))
    if ("urdf" in cfg.value) == ("example" in cfg.value):
        raise cfg.error("give exactly one of 'urdf' (a file) or 'example' (a robot name)")
    if "urdf" in cfg.value:
        dirs = [str((base_dir / d).resolve()) for d in cfg.get("package_dirs", [], types=list)]
        robot = load_urdf(base_dir / cfg.get("urdf", types=str), package_dirs=dirs)
    else:
        try:
            robot = load_example(cfg.get("example", types=str))
        except InputError as exc:
            raise cfg.error(exc.reason, "example") from None
    robot.base_placement = _se3(cfg.child("base"))
    frames = cfg.get("frames", [], types=list)
    for i, f in enumerate(frames):
        fc = Cfg(f, f"{cfg.path}.frames[{i}]", cfg.source)
        fc.require_mapping()
        try:
            robot.add_frame(fc.get("name", required=True, types=str), fc.get("parent", required=True, types=str),
                            _se3(fc))
        except InputError as exc:
            raise fc.error(exc.reason) from None
    return robot


def _joint_values(robot, tab: Table, joint_cols, rows, jn: Cfg) -> np.ndarray:
    cols = []
    for j, c in joint_cols.items():
        prismatic = robot.model.joints[robot.joint_id(j)].shortname().startswith("JointModelP")
        kind = "length" if prismatic else "angle"
        cols.append(tab.column(c, kind, jn.get(kind, "m" if prismatic else "rad"), rows))
    return np.column_stack(cols)


def _residual(cls, s: Cfg, tab: Table, rows, sample_idx, length_unit, angle_unit):
    sig = inspect.signature(cls.__init__)
    accepted = [p for p in sig.parameters if p not in ("self", "samples", "measurements", "columns")]
    reserved = ("type", "csv", "where", "columns", "samples")   # samples: used by `robocal simulate` only
    s.check_keys(tuple(accepted) + reserved)
    kwargs = {k: v for k, v in s.value.items() if k not in reserved}
    kwargs.setdefault("name", f"{s.value['type']}{s.path[s.path.index('[') + 1:-1]}")
    sigma = kwargs.get("sigma")
    if isinstance(sigma, dict):
        kwargs["sigma"] = (sigma.get("position", 1e-4), sigma.get("orientation", 1e-4))
    if "measurements" in sig.parameters:
        columns = s.get("columns", required=True, types=list)
        kinds = cls.column_kinds(len(columns))
        if len(kinds) != len(columns):
            raise s.error(f"{cls.type_name} needs {len(kinds)} columns, got {len(columns)}", "columns")
        data = [tab.column(str(c), k, length_unit if k == "length" else angle_unit, rows)
                for c, k in zip(columns, kinds)]
        kwargs["measurements"] = np.column_stack(data)
        kwargs["columns"] = [str(c) for c in columns]
    try:
        return cls(samples=sample_idx, **kwargs)
    except (TypeError, ValueError) as exc:
        raise s.error(str(exc)) from None


def _parameters(cfg: Cfg, robot, joint_names, frames) -> ParameterSet:
    if cfg.value is None:
        cfg = Cfg({}, cfg.path, cfg.source)
    cfg.check_keys(("preset", "joints", "frames", "base", "compliance", "backlash", "tilt", "fix", "free", "initial",
                    "priors", "bounds"))
    chain = [j for j in joint_names if any(j in robot.supporting_joints(f) for f in frames)]
    joints = cfg.get("joints", chain, types=list)
    fr = cfg.get("frames", {}, types=dict)
    frames_sel = {k: (True if v is True else list(v)) for k, v in fr.items() if v}
    base = cfg.get("base", False, types=(bool, list))
    try:
        return robot_parameters(robot, [str(j) for j in joints], cfg.get("preset", "full", types=str),
                                frames_sel, base, cfg.get("compliance", False, types=(bool, list)),
                                cfg.get("backlash", False, types=(bool, list)),
                                cfg.get("tilt", False, types=(bool, list)))
    except InputError as exc:
        raise cfg.error(exc.reason) from None


def _approach(cfg: Cfg, joint_names) -> ApproachSpec:
    cfg.check_keys(("from", "sort_by", "threshold", "initial", "columns"))
    spec = ApproachSpec(source=cfg.get("from", "order", types=str), sort_by=cfg.get("sort_by", types=str))
    if spec.source not in ("order", "columns"):
        raise cfg.error(f"unknown source '{spec.source}' (order, columns)", "from")
    th = cfg.child("threshold", {})
    th.check_keys(tuple(spec.threshold))
    for k in spec.threshold:
        spec.threshold[k] = float(th.get(k, spec.threshold[k], types=(int, float)))
        if not spec.threshold[k] >= 0:
            raise th.error("a threshold is a joint move (rad or m), zero or more", k)
    for key in ("initial", "columns"):
        given = cfg.get(key, {}, types=dict)
        unknown = [j for j in given if j not in joint_names]
        if unknown:
            raise cfg.error(f"'{unknown[0]}' is not a joint of data.joints", key)
        setattr(spec, key, {str(j): v if key == "initial" else str(v) for j, v in given.items()})
    if any(v not in (-1, 0, 1) for v in spec.initial.values()):
        raise cfg.error("initial directions are -1, 0 or 1", "initial")
    return spec


def _directions(cfg: Cfg, pcfg: Cfg, params: ParameterSet, robot, tables, samples, joint_cols, jn):
    """(N, n_joints) approach directions of the samples, or None without a data.approach section."""
    backlash = [p.target for p in params if p.kind == "joint_backlash"]
    if cfg.value is None:
        if backlash:
            raise pcfg.error("backlash needs the approach direction of every sample: add data.approach "
                             "(docs/config.md)", "backlash")
        return None
    joints = list(joint_cols)
    spec = _approach(cfg, joints)
    if spec.source == "columns":
        missing = [j for j in backlash if j not in spec.columns]
        if missing:
            raise cfg.error(f"joint '{missing[0]}' has a backlash parameter but no direction column", "columns")
    prismatic = [robot.model.joints[robot.joint_id(j)].shortname().startswith("JointModelP") for j in joints]
    out = np.zeros((len(samples), len(joints)))
    for file in dict.fromkeys(f for f, _ in samples):
        tab = tables[file]
        rows = np.arange(tab.n_rows)
        per_row = table_directions(tab, _joint_values(robot, tab, joint_cols, rows, jn), joints, prismatic, spec)
        for (f, r), i in samples.items():
            if f == file:
                out[i] = per_row[r]
    return out


def _parameter_overrides(cfg: Cfg, params: ParameterSet) -> None:
    if cfg.value is None:
        return
    try:
        params.fix(*cfg.get("fix", [], types=list))
        params.free(*cfg.get("free", [], types=list))
        for pat, v in cfg.get("initial", {}, types=dict).items():
            for n in params.select(pat):
                params[n].value = float(v)
        for pat, sigma in cfg.get("priors", {}, types=dict).items():
            for n in params.select(pat):
                params[n].prior_sigma, params[n].prior_mean = float(sigma), params[n].value
        for pat, (lo, hi) in cfg.get("bounds", {}, types=dict).items():
            for n in params.select(pat):
                params[n].min = -np.inf if lo is None else float(lo)
                params[n].max = np.inf if hi is None else float(hi)
    except InputError as exc:
        raise cfg.error(exc.reason) from None


def _solver(cfg: Cfg) -> CalibrationOptions:
    opt = CalibrationOptions()
    if cfg.value is None:
        return opt
    cfg.check_keys(tuple(vars(opt)))
    for k in vars(opt):
        if k in cfg.value:
            default = getattr(opt, k)
            setattr(opt, k, cfg.get(k, types=(str,) if isinstance(default, str) else
                                    (bool,) if isinstance(default, bool) else (int, float)))
    if opt.loss not in ("linear", "huber", "soft_l1"):
        raise cfg.error("loss must be linear, huber or soft_l1", "loss")
    return opt
