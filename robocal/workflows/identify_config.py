"""The dynamic-identification YAML (`robocal identify dyn.yaml`): parsing and model building.

Keys (paths relative to the YAML; units SI, torques in N m or N for prismatic joints):
  robot:   urdf; joints: the joints kept in the model (all others locked at their neutral value
           with pin.buildReducedModel)
  data:    position, velocity, effort: CSV files; time_column (default t); columns: optional
           {position|velocity|effort: pattern with {joint}} (default `- {joint}_position`, ...)
  effort:  recorded: joints whose effort was logged (the others stay in the model, give no rows);
           gear_ratio, motor_constant: {joint: value}: torque = effort x gear_ratio x motor_constant
           + torque_offset; torque_offset: {joint: value} a constant added to that torque (e.g. a
           torso whose effort excludes the weight it carries: + g x carried mass)
  signal:  cutoff_hz (auto), power_fraction, cutoff_margin, order, decimate (auto),
           velocity_source (logged|differentiated), edge_periods: see filtering.py
  windows: train: [t0, t1], validate: [t2, t3] (s, log time; must not overlap); min_motion (rad or
           m): the least position range a recorded joint must cover in the training window
  model:   terms: subset of [coulomb, viscous, offset, armature]; coulomb_width: the width of the
           tanh standing for sign(v), as a fraction of each joint's RMS speed in the training window
           (one number for revolute and prismatic joints alike);
           prior_rule: within_noise (default: the strongest CAD prior that keeps the consistent fit
           within the unconstrained fit's noise) or holdout (the weight that best predicts the
           training window's last part); prior_grid: lambda values to try; prior_split: share of
           the training window fitted by the holdout rule (the rest scores it); prior_weight.py
  wrench:  frame: where the external force is estimated (default: the last joint's child frame)
  output:  default output folder
See docs/dynamics_tiago.md for the worked TIAGo example.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from robocal.dynamics.identify_log import IdentifyOptions
from robocal.io.yaml_files import read_yaml
from robocal.workflows.config_keys import Cfg
from robocal.dynamics.prior_weight import DEFAULT_GRID, RULES
from robocal.dynamics.filtering import SignalOptions
from robocal.dynamics.regression import EXTRA_TERMS
from robocal.errors import InputError

TOP_KEYS = ("robot", "data", "effort", "signal", "windows", "model", "wrench", "output")
SIGNAL_KEYS = ("cutoff_hz", "power_fraction", "cutoff_margin", "order", "decimate", "nyquist_ratio",
               "velocity_source", "edge_periods")


@dataclass(kw_only=True)
class IdentifyConfig(IdentifyOptions):
    """The identification options and where the robot and the log come from (paths resolved)."""

    urdf: Path
    joints: list[str]
    files: dict[str, Path]
    time_column: str = "t"
    patterns: dict[str, str] = field(default_factory=dict)
    recorded: list[str]
    torque_scale: dict[str, float]
    torque_offset: dict[str, float] = field(default_factory=dict)
    output: Path | None = None


def load_identify_config(path_or_dict, base_dir: str | Path | None = None) -> IdentifyConfig:
    """Parse a YAML file (path) or an already-loaded mapping (then `base_dir` resolves its paths)."""
    if isinstance(path_or_dict, dict):
        raw, source = path_or_dict, "config"
        base = Path(base_dir or ".").resolve()
    else:
        path = Path(path_or_dict).resolve()
        raw, source = read_yaml(path), str(path)
        base = Path(base_dir).resolve() if base_dir else path.parent
    root = Cfg(raw, "", source)
    root.check_keys(TOP_KEYS)
    robot, data, effort = root.child("robot"), root.child("data"), root.child("effort")
    robot.check_keys(("urdf", "joints"))
    data.check_keys(("position", "velocity", "effort", "time_column", "columns"))
    effort.check_keys(("recorded", "gear_ratio", "motor_constant", "torque_offset"))
    joints = _names(robot, "joints")
    files = {k: base / str(data.get(k, required=True, types=str)) for k in ("position", "velocity", "effort")}
    recorded = _names(effort, "recorded")
    for name in recorded:
        if name not in joints:
            raise effort.error(f"'{name}' is not one of robot.joints", "recorded")
    gear, kmotor = _per_joint(effort, "gear_ratio", recorded), _per_joint(effort, "motor_constant", recorded)
    offsets = effort.get("torque_offset", {}, types=dict)
    for name in offsets:
        if name not in recorded:
            raise effort.error(f"'{name}' is not a recorded joint", "torque_offset")
    signal = root.child("signal", {})
    signal.check_keys(SIGNAL_KEYS)
    opts = dict(signal.value or {})
    for key in ("cutoff_hz", "decimate"):
        if opts.get(key) == "auto":
            opts[key] = None
    windows, model, wrench = root.child("windows"), root.child("model", {}), root.child("wrench", {})
    windows.check_keys(("train", "validate", "min_motion"))
    model.check_keys(("terms", "coulomb_width", "prior_rule", "prior_grid", "prior_split"))
    wrench.check_keys(("frame",))
    train, validate = _window(windows, "train"), _window(windows, "validate")
    if train[0] < validate[1] and validate[0] < train[1]:
        raise windows.error(f"train {list(train)} and validate {list(validate)} overlap: validation must be "
                            "held out", "validate")
    columns = data.get("columns", {}, types=dict)
    out = root.get("output")
    try:
        cfg = IdentifyConfig(
            source=source, urdf=base / str(robot.get("urdf", required=True, types=str)), joints=joints,
            files=files, time_column=str(data.get("time_column", "t", types=str)),
            patterns={str(k): str(v) for k, v in columns.items()}, recorded=recorded,
            torque_scale={j: gear[j] * kmotor[j] for j in recorded},
            torque_offset={str(k): float(v) for k, v in offsets.items()}, signal=SignalOptions(**opts),
            train=train, validate=validate, min_motion=float(windows.get("min_motion", 0.01, types=(int, float))),
            terms=tuple(model.get("terms", list(EXTRA_TERMS), types=list)),
            coulomb_width=float(model.get("coulomb_width", 0.05, types=(int, float))),
            prior_grid=tuple(float(x) for x in model.get("prior_grid", list(DEFAULT_GRID), types=list)),
            prior_split=float(model.get("prior_split", 0.75, types=(int, float))),
            wrench_frame=wrench.get("frame", None, types=str), output=None if out is None else base / str(out),
            prior_rule=str(model.get("prior_rule", "within_noise", types=str)))
    except TypeError as exc:
        raise InputError(f"bad value: {exc}", source=source, field="signal") from None
    except InputError as exc:              # SignalOptions knows the key, not the file
        raise InputError(exc.reason, source=source, field=exc.field) from None
    if not cfg.coulomb_width > 0:
        raise model.error("coulomb_width must be > 0", "coulomb_width")
    if cfg.prior_rule not in RULES:
        raise model.error(f"prior_rule must be one of {', '.join(RULES)}, not '{cfg.prior_rule}'", "prior_rule")
    if not cfg.prior_grid or not all(g > 0 for g in cfg.prior_grid):
        raise model.error("prior_grid must hold positive weights", "prior_grid")
    if not 0.3 <= cfg.prior_split < 1:
        raise model.error("prior_split must lie in [0.3, 1)", "prior_split")
    return cfg


def _names(cfg: Cfg, key: str) -> list[str]:
    names = cfg.get(key, required=True, types=list)
    if not names or not all(isinstance(n, str) for n in names) or len(set(names)) != len(names):
        raise cfg.error("expected a non-empty list of distinct joint names", key)
    return list(names)


def _per_joint(cfg: Cfg, key: str, joints: list[str]) -> dict[str, float]:
    values = cfg.get(key, required=True, types=dict)
    for j in joints:
        if j not in values or not isinstance(values[j], (int, float)) or values[j] == 0:
            raise cfg.error(f"needs a non-zero number for every recorded joint; '{j}' has "
                            f"{values.get(j)!r}", key)
    return {j: float(values[j]) for j in joints}


def _window(cfg: Cfg, key: str) -> tuple[float, float]:
    w = cfg.get(key, required=True, types=list)
    if len(w) != 2 or not all(isinstance(x, (int, float)) for x in w) or not w[0] < w[1]:
        raise cfg.error("expected [start, stop] in seconds with start < stop", key)
    return float(w[0]), float(w[1])
