"""The dynamic-identification YAML (`robocal identify dyn.yaml`): parsing and model building.

Keys (paths relative to the YAML; units SI, torques in N m or N for prismatic joints):
  robot:   urdf; joints: the joints kept in the model (all others locked at their neutral value
           with pin.buildReducedModel)
  logs:    a list of logs, each: position, velocity, effort: CSV files; time_column (default t);
           columns: optional {position|velocity|effort: pattern with {joint}} (default `- {joint}_position`,
           ...); train: [t0, t1] or a list of such windows (s, log time); validate: the same (optional: a
           log may only train, or only validate); name (optional). The same files may be listed twice
           with other windows; sample_period_s: the rows' period when the log has no time column.
           With a transmission a log is motor-side: position (motor encoders) and effort (motor currents or
           torques) only, columns patterns with {motor} (default `{motor}_position`, `{motor}_effort`; one
           file may hold both).
  data:    one log (position, velocity, effort, time_column, columns) with windows: train, validate:
           the single-log form of `logs` (either logs or data, not both)
  windows: min_motion (rad or m): the least position range a recorded joint must cover in the training
           windows; with `data`, also train and validate (one window each)
  effort:  recorded: joints whose effort was logged (the others stay in the model, give no rows);
           gear_ratio, motor_constant: {joint: value}: torque = effort x gear_ratio x motor_constant
           + torque_offset; torque_offset: {joint: value} a constant added to that torque (e.g. a
           torso whose effort excludes the weight it carries: + g x carried mass). With a transmission:
           recorded only, the motors whose efforts were logged (default: all)
  transmission: the motors and the motor-to-joint map q = T m + c (motors, ratio, coupling or matrix,
           offset, effort: current|torque, motor_constant): robocal.dynamics.transmission_config
  signal:  cutoff_hz (auto), power_fraction, cutoff_margin, order, decimate (auto),
           velocity_source (logged|differentiated|auto), edge_periods: see filtering.py; max_rate_hz
           (default 250): faster logs are first reduced to at most this rate (rate_reduction.py)
  model:   terms: always in the model, subset of [coulomb, viscous, offset, armature, spring,
           coulomb_asymmetric, viscous_asymmetric]; motor_terms: with a transmission, per logged motor, subset
           of [coulomb, viscous, offset, armature] (default none); candidate_terms: tried per recorded joint and kept
           when the training data show them (spring, coulomb_asymmetric, viscous_asymmetric, delay;
           term_selection.py); delay_max_s: the largest delay tried (s); coulomb_width: the width of the
           tanh standing for sign(v), as a fraction of each joint's RMS speed over the training samples;
           prior_rule: within_bounds_noise (default), within_noise or holdout (prior_weight.py);
           prior_grid: lambda values to try; prior_split: share of the training samples fitted by the
           holdout rule; plausible: false, or {mass_ratio: [low, high] x CAD mass (default [0.5, 2]),
           margin_m: padding of the geometry box (default 0.05), ellipsoids: {joint: {center: [x, y, z],
           semi_axes: [a, b, c]}} (m, joint frame)} (plausible_bounds.py; default on)
  wrench:  frame: where the external force is estimated (default: the last joint's child frame)
  output:  default output folder
See docs/dynamics_tiago.md for the worked TIAGo example.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from robocal.dynamics.channels import MOTOR_TERMS
from robocal.dynamics.identify_log import IdentifyOptions
from robocal.dynamics.plausible_bounds import MARGIN_M, MASS_RATIO, check_ellipsoids
from robocal.dynamics.transmission import Transmission
from robocal.dynamics.transmission_config import transmission_from_config
from robocal.io.yaml_files import read_yaml
from robocal.workflows.config_keys import Cfg
from robocal.dynamics.prior_weight import DEFAULT_GRID, RULES
from robocal.dynamics.filtering import SignalOptions
from robocal.dynamics.regression import EXTRA_TERMS, REPLACES, TERMS
from robocal.dynamics.term_selection import CANDIDATES
from robocal.errors import InputError

TOP_KEYS = ("robot", "logs", "data", "effort", "transmission", "signal", "windows", "model", "wrench", "output")
SIGNAL_KEYS = ("cutoff_hz", "power_fraction", "cutoff_margin", "order", "decimate", "nyquist_ratio",
               "velocity_source", "edge_periods", "max_rate_hz")
LOG_KEYS = ("name", "position", "velocity", "effort", "time_column", "sample_period_s", "columns", "train",
            "validate")
MODEL_KEYS = ("terms", "motor_terms", "candidate_terms", "delay_max_s", "coulomb_width", "prior_rule",
              "prior_grid", "prior_split", "plausible")


@dataclass
class LogSpec:
    """One log of the config: files {kind: path} (position, velocity, effort; a motor-side log position and
    effort), time_column or sample_period (s, no time column), column patterns, its windows (lists of
    (t0, t1) s) and a name for messages."""

    files: dict[str, Path]
    train: list[tuple[float, float]]
    validate: list[tuple[float, float]]
    time_column: str = "t"
    patterns: dict[str, str] = field(default_factory=dict)
    name: str = "log"
    sample_period: float | None = None


@dataclass(kw_only=True)
class IdentifyConfig(IdentifyOptions):
    """The identification options and where the robot and the logs come from (paths resolved)."""

    urdf: Path
    joints: list[str]
    logs: list[LogSpec]
    recorded: list[str]
    torque_scale: dict[str, float]
    torque_offset: dict[str, float] = field(default_factory=dict)
    output: Path | None = None
    transmission: Transmission | None = None


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
    robot, effort = root.child("robot"), root.child("effort")
    robot.check_keys(("urdf", "joints"))
    joints = _names(robot, "joints")
    windows = root.child("windows", {})
    motor_side = root.get("transmission") is not None
    logs = _logs(root, windows, base, motor_side)
    if motor_side:
        effort = root.child("effort", {})
        effort.check_keys(("recorded",))           # gear ratios and constants are the transmission's
        recorded = _names(effort, "recorded") if effort.get("recorded") is not None else None
        transmission = transmission_from_config(root.get("transmission"), joints, recorded, source)
        recorded = recorded or list(transmission.motors)
        gear = kmotor = {m: 1.0 for m in recorded}
        offsets = {}
    else:
        effort.check_keys(("recorded", "gear_ratio", "motor_constant", "torque_offset"))
        transmission = None
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
    model, wrench = root.child("model", {}), root.child("wrench", {})
    model.check_keys(MODEL_KEYS)
    wrench.check_keys(("frame",))
    terms, candidates = _terms(model)
    motor_terms = tuple(model.get("motor_terms", [], types=list))
    for t in motor_terms:
        if t not in MOTOR_TERMS or not motor_side:
            raise model.error(f"unknown motor term '{t}'; known: {', '.join(MOTOR_TERMS)}" if motor_side else
                              "motor terms need a transmission section (motor-side logs)", "motor_terms")
    plausible = _plausible(model.child("plausible", {}), joints)
    out = root.get("output")
    try:
        cfg = IdentifyConfig(
            source=source, urdf=base / str(robot.get("urdf", required=True, types=str)), joints=joints,
            logs=logs, recorded=recorded, torque_scale={j: gear[j] * kmotor[j] for j in recorded},
            torque_offset={str(k): float(v) for k, v in offsets.items()}, signal=SignalOptions(**opts),
            min_motion=float(windows.get("min_motion", 0.01, types=(int, float))),
            terms=terms, motor_terms=motor_terms, transmission=transmission,
            candidate_terms=candidates, delay_max_s=model.number("delay_max_s", 0.2, positive=True),
            coulomb_width=float(model.get("coulomb_width", 0.05, types=(int, float))),
            prior_grid=tuple(float(x) for x in model.get("prior_grid", list(DEFAULT_GRID), types=list)),
            prior_split=float(model.get("prior_split", 0.75, types=(int, float))),
            wrench_frame=wrench.get("frame", None, types=str), output=None if out is None else base / str(out),
            prior_rule=str(model.get("prior_rule", "within_bounds_noise", types=str)), **plausible)
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


def _logs(root: Cfg, windows: Cfg, base: Path, motor_side: bool = False) -> list[LogSpec]:
    """`logs:` entries, or the single-log form `data:` + `windows:`; windows checked (held out, in order).
    motor_side: the logs hold motor positions and efforts (no velocity file)."""
    if root.get("logs") is not None and root.get("data") is not None:
        raise root.error("give either logs (a list) or data (one log), not both", "data")
    if root.get("logs") is None:
        data = root.child("data")
        data.check_keys(("position", "velocity", "effort", "time_column", "sample_period_s", "columns"))
        windows.check_keys(("train", "validate", "min_motion"))
        entries = [(data, {**data.value, "train": windows.get("train", required=True),
                           "validate": windows.get("validate")}, windows)]
    else:
        windows.check_keys(("min_motion",))
        listed = root.get("logs", types=list)
        if not listed:
            raise root.error("expected a non-empty list of logs", "logs")
        entries = []
        for i, entry in enumerate(listed):
            c = Cfg(entry, f"logs[{i}]", root.source)
            c.check_keys(LOG_KEYS)
            entries.append((c, entry, c))
    out = []
    for i, (c, entry, wc) in enumerate(entries):
        kinds = ("position", "effort") if motor_side else ("position", "velocity", "effort")
        if motor_side and c.get("velocity") is not None:
            raise c.error("a motor-side log holds motor positions and efforts: velocities are differentiated from "
                          "the encoders", "velocity")
        files = {k: base / str(c.get(k, required=True, types=str)) for k in kinds}
        period = c.get("sample_period_s")
        if period is not None:
            period = c.number("sample_period_s", 0.0, positive=True)
            if c.get("time_column") is not None:
                raise c.error("give time_column or sample_period_s, not both", "sample_period_s")
        train = _windows(wc, "train", entry.get("train"))
        validate = _windows(wc, "validate", entry.get("validate"))
        for a in train:
            for b in validate:
                if a[0] < b[1] and b[0] < a[1]:
                    raise wc.error(f"train {list(a)} and validate {list(b)} overlap: validation must be held out",
                                   "validate")
        out.append(LogSpec(files, train, validate, str(c.get("time_column", "t", types=str)),
                           {str(k): str(v) for k, v in c.get("columns", {}, types=dict).items()},
                           str(entry.get("name", f"log {i + 1}")), period))
    _check_reuse(out, root)
    return out


def _check_reuse(logs: list[LogSpec], root: Cfg) -> None:
    """The same files listed twice: one entry's validation may not be another's training."""
    for i, a in enumerate(logs):
        for j, b in enumerate(logs):
            if i != j and a.files["position"].resolve() == b.files["position"].resolve():
                for w in a.validate:
                    for v in b.train:
                        if w[0] < v[1] and v[0] < w[1]:
                            raise root.error(f"'{a.name}' validates on {list(w)} s, which '{b.name}' trains on "
                                             "(same files): validation must be held out", f"logs[{j}].train")


def _windows(c: Cfg, key: str, value) -> list[tuple[float, float]]:
    """[t0, t1] or a list of such (s); none for a missing validate."""
    if value is None:
        if key == "train":
            raise c.error("required key is missing", key)
        return []
    items = [value] if isinstance(value, list) and len(value) == 2 and all(
        isinstance(x, (int, float)) for x in value) else value
    if not isinstance(items, list) or not items:
        raise c.error("expected [start, stop] in seconds, or a list of them", key)
    out = []
    for w in items:
        if not (isinstance(w, list) and len(w) == 2 and all(isinstance(x, (int, float)) for x in w) and w[0] < w[1]):
            raise c.error("expected [start, stop] in seconds with start < stop", key)
        out.append((float(w[0]), float(w[1])))
    return out


def _terms(model: Cfg) -> tuple[tuple[str, ...], tuple[str, ...]]:
    terms = tuple(model.get("terms", list(EXTRA_TERMS), types=list))
    candidates = tuple(model.get("candidate_terms", [], types=list))
    for t in terms:
        if t not in TERMS:
            raise model.error(f"unknown term '{t}'; known: {', '.join(TERMS)}", "terms")
    for t in candidates:
        if t not in CANDIDATES:
            raise model.error(f"unknown candidate term '{t}'; known: {', '.join(CANDIDATES)}", "candidate_terms")
        if t in REPLACES and REPLACES[t] not in terms:
            raise model.error(f"'{t}' is tried against '{REPLACES[t]}', which model.terms must hold", "candidate_terms")
        if t in terms:
            raise model.error(f"'{t}' is in model.terms already", "candidate_terms")
    return terms, candidates


def _plausible(c: Cfg, joints: list[str]) -> dict:
    if c.value is False:
        return {"plausible": False}
    c.check_keys(("mass_ratio", "margin_m", "ellipsoids"))
    ratio = c.get("mass_ratio", list(MASS_RATIO), types=list)
    if len(ratio) != 2 or not all(isinstance(x, (int, float)) for x in ratio) or not 0 <= ratio[0] <= 1 <= ratio[1]:
        raise c.error("expected [low, high] with 0 <= low <= 1 <= high", "mass_ratio")
    return {"plausible": True, "mass_ratio": (float(ratio[0]), float(ratio[1])),
            "margin_m": c.number("margin_m", MARGIN_M, positive=True),
            "ellipsoids": check_ellipsoids(c.get("ellipsoids", {}), joints, c.source)}


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


