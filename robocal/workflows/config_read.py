"""Read a calibration YAML once into typed objects (config_types.py), checking every key, type and value
that does not need the robot or the data; those are checked when the set-up is built (setup.py).

Every mistake names the file and the key path (`measurements[1].sigma.position`). Units: see
docs/config.md, "Units" (measurement columns and their sigmas in `data.units`).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from robocal.design.candidates import MeasurementVolume
from robocal.errors import InputError
from robocal.estimation.calibrate import CalibrationOptions
from robocal.estimation.sessions import SESSION_FRAMES
from robocal.io.tables import ANGLE_UNITS, LENGTH_UNITS
from robocal.io.yaml_files import read_yaml
from robocal.model.approach import ApproachSpec
from robocal.model.parameters import COMPONENTS
from robocal.residuals import REGISTRY
from robocal.workflows.config_camera import camera_block_config
from robocal.workflows.config_keys import FILLED_BY_CONFIG, TOP_KEYS, Cfg, check_keys
from robocal.workflows.config_types import (CalibrationConfig, CandidatesConfig, DataConfig, FrameSpec,
                                            Iso9283Config, MeasurementConfig, OutputConfig, ParametersConfig,
                                            Placement, PlanConfig, RobotConfig, SessionSpec, SimulationConfig,
                                            Units)
from robocal.workflows.config_measurements import accepts_measurements, residual_class, row_kinds, sigma_argument

#: keys of a block that are not its type's own settings
RESERVED = ("type", "name", "frame", "csv", "where", "columns", "sigma", "samples")


def read_config(path: str | Path) -> CalibrationConfig:
    """The checked config of a calibration YAML file (paths relative to its folder)."""
    path = Path(path).resolve()
    return parse_config(read_yaml(path), path.parent, str(path))


def parse_config(raw, base_dir: str | Path, source: str) -> CalibrationConfig:
    """The checked config of a parsed YAML mapping; paths relative to base_dir, `source` names it in errors."""
    if not isinstance(raw, dict):
        raise InputError(f"the config is empty or not a mapping of sections ({', '.join(TOP_KEYS)})", source=source)
    check_keys(raw, source)
    base_dir = Path(base_dir).resolve()
    root = Cfg(raw, "", source)
    data = data_config(root.child("data", {}), base_dir)
    out = root.child("output", {})
    out.require_mapping()
    measurements = measurement_configs(root.child("measurements"), base_dir, data)
    return CalibrationConfig(
        source, base_dir, robot_config(root.child("robot"), base_dir), data,
        parameters_config(root.child("parameters")), measurements,
        solver_options(root.child("solver")),
        OutputConfig((base_dir / out.get("dir", "robocal-output", types=str)).resolve(),
                     bool(out.get("report", True, types=bool))),
        simulation_config(root.child("simulation")) if "simulation" in raw else None,
        plan_config(root.child("plan", {}), base_dir, data, measured_kinds(measurements)) if "plan" in raw else None,
        iso9283_config(root.child("iso9283")) if "iso9283" in raw else None)


def with_parameters(config: CalibrationConfig, overrides: dict) -> CalibrationConfig:
    """The config with keys of its `parameters:` section replaced (YAML form, checked as the file's are)."""
    merged = {**config.parameters.to_dict(), **overrides}
    check_keys({"parameters": merged}, config.source)
    return dataclasses.replace(config, parameters=parameters_config(Cfg(merged, "parameters", config.source)))


def robot_config(cfg: Cfg, base_dir: Path) -> RobotConfig:
    if cfg.value is None:
        raise cfg.error("required section is missing (give robot.urdf, robot.mjcf or robot.example)")
    cfg.require_mapping()
    if sum(key in cfg.value for key in ("urdf", "example", "mjcf")) != 1:
        raise cfg.error("give exactly one of 'urdf' (a file), 'mjcf' (a file) or 'example' (a robot name)")
    if "actuated" in cfg.value and "mjcf" not in cfg.value:
        raise cfg.error("'actuated' goes with 'mjcf' (a URDF names its actuated joints in <actuated>)", "actuated")
    frames = []
    for i, f in enumerate(cfg.get("frames", [], types=list)):
        fc = Cfg(f, f"{cfg.path}.frames[{i}]", cfg.source)
        fc.require_mapping()
        frames.append(FrameSpec(fc.get("name", required=True, types=str), fc.get("parent", required=True, types=str),
                                placement(fc)))
    urdf, mjcf, actuated = cfg.get("urdf", types=str), cfg.get("mjcf", types=str), cfg.get("actuated", types=list)
    return RobotConfig(None if urdf is None else (base_dir / urdf).resolve(), cfg.get("example", types=str),
                       tuple((base_dir / str(d)).resolve() for d in cfg.get("package_dirs", [], types=list)),
                       placement(cfg.child("base")), tuple(frames), None if mjcf is None else (base_dir / mjcf).resolve(),
                       None if actuated is None else tuple(str(j) for j in actuated))


def placement(cfg: Cfg) -> Placement:
    """xyz (m) and rpy (rad) of a mapping (identity when absent)."""
    if cfg.value is None:
        return Placement()
    cfg.require_mapping()
    out = []
    for key in ("xyz", "rpy"):
        v = cfg.get(key, [0, 0, 0], types=list)
        if len(v) != 3 or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)
                                  for x in v):
            raise cfg.error(f"expected three finite numbers, got {v!r}", key)
        out.append(tuple(float(x) for x in v))
    return Placement(out[0], out[1])


def units_of(node: Cfg) -> Units:
    node.require_mapping()
    units = Units(node.get("length", "m", types=str), node.get("angle", "rad", types=str))
    for kind, allowed in (("length", LENGTH_UNITS), ("angle", ANGLE_UNITS)):
        if getattr(units, kind) not in allowed:
            raise node.error(f"unknown unit '{getattr(units, kind)}' (allowed: {', '.join(allowed)})", kind)
    return units


def data_config(data: Cfg, base_dir: Path) -> DataConfig:
    data.require_mapping()
    joints = data.get("joints")
    if isinstance(joints, list):
        joints = {str(j): str(j) for j in joints}
    elif isinstance(joints, dict):
        joints = {str(k): str(v) for k, v in joints.items()}
    elif joints is not None:
        raise data.error("expected a list of joint names or a mapping joint -> column", "joints")
    csv = data.get("csv", types=str)
    approach = data.child("approach")
    sessions = session_specs(data, base_dir)
    column = data.get("session_column", types=str)
    if sessions and (csv is not None or column is not None):
        raise data.error("give the data as data.sessions (one CSV per session), or as data.csv with an optional "
                         "data.session_column, not both", "sessions")
    return DataConfig(None if csv is None else (base_dir / csv).resolve(), joints, units_of(data.child("units", {})),
                      units_of(data.child("joint_units", {})),
                      None if approach.value is None else approach_spec(approach), sessions, column)


def session_specs(data: Cfg, base_dir: Path) -> tuple[SessionSpec, ...]:
    """`data.sessions`: a list of {name, csv}, names distinct."""
    out = []
    for i, s in enumerate(data.get("sessions", [], types=list)):
        node = Cfg(s, f"data.sessions[{i}]", data.source)
        node.require_mapping()
        name = str(node.get("name", required=True, types=(str, int)))
        if any(o.name == name for o in out) or "@" in name or not name.strip():
            raise node.error(f"session names must be distinct, non-empty and without '@', got {name!r}", "name")
        out.append(SessionSpec(name, (base_dir / node.get("csv", required=True, types=str)).resolve()))
    if len(out) == 1:
        raise data.error("one session is no sessions: give data.csv instead, or list two or more", "sessions")
    return tuple(out)


def approach_spec(cfg: Cfg) -> ApproachSpec:
    """`data.approach`: how the approach direction of each sample is known (joint names checked at set-up)."""
    cfg.require_mapping()
    spec = ApproachSpec(source=cfg.get("from", "order", types=str), sort_by=cfg.get("sort_by", types=str))
    if spec.source not in ("order", "columns"):
        raise cfg.error(f"unknown source '{spec.source}' (order, columns)", "from")
    th = cfg.child("threshold", {})
    th.require_mapping()
    for k in spec.threshold:
        spec.threshold[k] = float(th.get(k, spec.threshold[k], types=(int, float)))
        if not spec.threshold[k] >= 0:
            raise th.error("a threshold is a joint move (rad or m), zero or more", k)
    spec.initial = {str(j): v for j, v in cfg.get("initial", {}, types=dict).items()}
    spec.columns = {str(j): str(v) for j, v in cfg.get("columns", {}, types=dict).items()}
    if any(v not in (-1, 0, 1) for v in spec.initial.values()):
        raise cfg.error("initial directions are -1, 0 or 1", "initial")
    return spec


def components(cfg: Cfg, key: str, value):
    """True / False, or a list of tx ... rz components as a tuple."""
    if value is True or value is False:
        return value
    if isinstance(value, list) and set(map(str, value)) <= set(COMPONENTS):
        return tuple(str(c) for c in value)
    raise cfg.error(f"expected true or a list of {', '.join(COMPONENTS)}, got {value!r}", key)


def parameters_config(cfg: Cfg) -> ParametersConfig:
    if cfg.value is None:
        return ParametersConfig()
    cfg.require_mapping()
    frames = {}
    for name, v in cfg.get("frames", {}, types=dict).items():
        frames[str(name)] = components(cfg.child("frames"), str(name), v)
    joints = cfg.get("joints", types=list)
    kinds = {k: cfg.get(k, False, types=(bool, list)) for k in ("base", "compliance", "backlash", "tilt")}
    kinds["base"] = components(cfg, "base", kinds["base"])
    kinds.update({k: v if isinstance(v, bool) else tuple(str(j) for j in v)
                  for k, v in kinds.items() if k != "base"})
    return ParametersConfig(cfg.get("preset", "full", types=str), None if joints is None else tuple(map(str, joints)),
                            frames, kinds["base"], kinds["compliance"], kinds["backlash"], kinds["tilt"],
                            tuple(map(str, cfg.get("fix", [], types=list))),
                            tuple(map(str, cfg.get("free", [], types=list))),
                            numbers_by_pattern(cfg, "initial"), numbers_by_pattern(cfg, "priors", positive=True),
                            bounds_by_pattern(cfg), per_session(cfg))


def per_session(cfg: Cfg) -> tuple[str, ...]:
    """`parameters.per_session`: the frames re-registered in every session (default: the measurement frame)."""
    frames = cfg.get("per_session", ["base"], types=list)
    unknown = [f for f in frames if f not in SESSION_FRAMES]
    if unknown:
        raise cfg.error(f"a session re-registers {', '.join(SESSION_FRAMES)} (the measurement frame) only, not "
                        f"{', '.join(map(str, unknown))}", "per_session")
    return tuple(frames)


def numbers_by_pattern(cfg: Cfg, key: str, positive: bool = False) -> dict[str, float]:
    node = cfg.child(key)
    out = {}
    for pattern, v in cfg.get(key, {}, types=dict).items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            raise node.error(f"expected a finite number, got {v!r}", str(pattern))
        if positive and not v > 0:
            raise node.error(f"a prior sigma must be positive, got {v!r}", str(pattern))
        out[str(pattern)] = float(v)
    return out


def bounds_by_pattern(cfg: Cfg) -> dict[str, tuple[float | None, float | None]]:
    node = cfg.child("bounds")
    out = {}
    for pattern, bound in cfg.get("bounds", {}, types=dict).items():
        if not (isinstance(bound, list) and len(bound) == 2
                and all(b is None or (isinstance(b, (int, float)) and not isinstance(b, bool)) for b in bound)):
            raise node.error(f"expected [low, high], got {bound!r}", str(pattern))
        out[str(pattern)] = tuple(None if b is None else float(b) for b in bound)
    return out


def measurement_configs(meas: Cfg, base_dir: Path, data: DataConfig) -> tuple[MeasurementConfig, ...]:
    if not isinstance(meas.value, list) or not meas.value:
        raise meas.error("need a list of at least one measurement block")
    return tuple(measurement_config(Cfg(m, f"measurements[{i}]", meas.source), i, base_dir, data)
                 for i, m in enumerate(meas.value))


def measurement_config(b: Cfg, i: int, base_dir: Path, data: DataConfig) -> MeasurementConfig:
    b.require_mapping()
    cls = residual_class(b)
    frame = b.get("frame", required=True, types=str)
    where = b.get("where", types=dict)
    if where is not None and len(where) != 1:
        raise b.error("where selects rows by one column: {column: value}", "where")
    if cls.type_name == "camera":      # its own keys, no columns (config_camera.py)
        camera, sigma = camera_block_config(b, base_dir, placement)
        csv = b.get("csv", types=str)
        return MeasurementConfig(cls.type_name, b.get("name", f"{cls.type_name}{i}", types=str), frame, b.path,
                                 None if csv is None else (base_dir / csv).resolve(),
                                 None if where is None else next(iter(where.items())), sigma=sigma, camera=camera)
    columns = b.get("columns", None, types=list)
    if accepts_measurements(cls):
        if columns is None:
            raise b.error("required key is missing", "columns")
        kinds = cls.column_kinds(len(columns))
        if len(kinds) != len(columns):
            raise b.error(f"{cls.type_name} needs {len(kinds)} columns, got {len(columns)}", "columns")
    csv = b.get("csv", types=str)
    samples = b.get("samples", types=int)
    if samples is not None and samples < 1:
        raise b.error("need at least one sample", "samples")
    sigma = b.value.get("sigma")
    return MeasurementConfig(
        cls.type_name, b.get("name", f"{cls.type_name}{i}", types=str), frame, b.path,
        None if csv is None else (base_dir / csv).resolve(), None if where is None else next(iter(where.items())),
        tuple(str(c) for c in columns or ()),
        None if sigma is None else sigma_argument(sigma, b, data.units, row_kinds(cls)),
        {k: v for k, v in b.value.items() if k not in RESERVED and k not in FILLED_BY_CONFIG}, samples)


def simulation_config(sim: Cfg) -> SimulationConfig:
    if sim.value is None:
        return SimulationConfig()
    sim.require_mapping()
    spans = sim.child("perturb", {})
    spans.require_mapping()
    samples = sim.get("samples", 60, types=int)
    if samples < 1:
        raise sim.error("need at least one sample", "samples")
    truth = sim.get("truth", {}, types=dict)
    for name, v in truth.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise sim.child("truth").error(f"expected a number, got {v!r}", str(name))
    return SimulationConfig(sim.get("seed", 0, types=int), samples, spans.number("translation", 2e-3),
                            spans.number("rotation", np.radians(0.2)), {str(k): float(v) for k, v in truth.items()})


def measured_kinds(measurements) -> frozenset[str] | None:
    """The quantities ('length', 'angle') the rows of every block hold together; None when a type does not say
    (robocal plan's noise replaces every block's sigma, so a labelled one must measure what they all measure)."""
    kinds = [row_kinds(REGISTRY[m.type]) for m in measurements]
    return None if not kinds or any(k is None for k in kinds) else frozenset().union(*kinds)


def plan_config(plan: Cfg, base_dir: Path, data: DataConfig, kinds: frozenset[str] | None = None) -> PlanConfig:
    plan.require_mapping()
    cand = plan.child("candidates", {})
    cand.require_mapping()
    method = cand.get("method", "random", types=str)
    if method not in ("random", "grid"):
        raise cand.error("method must be random or grid", "method")
    levels = cand.get("levels", 4, types=(int, list))
    candidates = CandidatesConfig(method, cand.get("count", 1000, types=int),
                                  float(cand.get("margin", 0.05, types=(int, float))),
                                  levels if isinstance(levels, int) else tuple(levels),
                                  float(cand.get("min_singular", 0.02, types=(int, float))),
                                  float(cand.get("length_scale", 0.5, types=(int, float))))
    noise = plan.get("noise")
    curve = plan.get("curve", None, types=list)
    out = plan.child("output", {})
    out.require_mapping()
    return PlanConfig(plan.get("frame", types=str), plan.get("N", 30, types=int), plan.get("criterion", "D", types=str),
                      plan.get("seed", 0, types=int),
                      None if noise is None else sigma_argument(noise, Cfg({"sigma": noise}, "plan.noise", plan.source),
                                                                data.units, kinds),
                      candidates, MeasurementVolume.from_dict(plan.get("volume"), plan.source, "plan.volume"),
                      plan.get("validation", 200, types=int), None if curve is None else tuple(int(c) for c in curve),
                      (base_dir / out.get("dir", "robocal-plan", types=str)).resolve())


def iso9283_config(sec: Cfg) -> Iso9283Config:
    if sec.value is None:
        raise sec.error("the config needs an 'iso9283' section (pose_id, measurement, commanded)")
    sec.require_mapping()
    cols = sec.get("commanded", types=list)
    if cols is not None and len(cols) != 7:
        raise sec.error(f"commanded needs 7 columns (x y z qx qy qz qw), got {len(cols)}", "commanded")
    pairs = sec.get("distance_pairs", types=list)
    if pairs is not None and not all(isinstance(p, list) and len(p) == 2 for p in pairs):
        raise sec.error("expected a list of [pose, pose] pairs", "distance_pairs")
    return Iso9283Config(sec.get("pose_id", required=True, types=str), sec.get("measurement", types=str),
                         None if cols is None else tuple(str(c) for c in cols),
                         None if pairs is None else tuple((str(a), str(b)) for a, b in pairs))



def solver_options(cfg: Cfg) -> CalibrationOptions:
    opt = CalibrationOptions()
    if cfg.value is None:
        return opt
    cfg.require_mapping()
    for k in vars(opt):
        if k in cfg.value:
            default = getattr(opt, k)
            setattr(opt, k, cfg.get(k, types=(str,) if isinstance(default, str) else
                                    (bool,) if isinstance(default, bool) else (int, float)))
    if opt.loss not in ("linear", "huber", "soft_l1"):
        raise cfg.error("loss must be linear, huber or soft_l1", "loss")
    return opt
