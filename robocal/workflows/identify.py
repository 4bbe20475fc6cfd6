"""`robocal identify dyn.yaml`: read the config and the logs, check them, identify, and return the result.

The identification itself is robocal.dynamics.identify_log; identify_outputs.py writes the folder.
Checks before any fit (a clear error naming file, row and field, or a note when the data stay usable):
the URDF's inertials (urdf_checks.py), each log's windows, motion, joint limits and recorded efforts.
With a transmission the logs are motor-side (motor_log.py): joint positions through q = T m + c, the rows the
logged motors' torques (channels.py). See docs/dynamics_tiago.md and docs/dynamics_motors.md.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from robocal.dynamics.channels import Channels
from robocal.dynamics.effort_map import EffortMap
from robocal.dynamics.identify_log import IdentifyResult, identify_log
from robocal.dynamics.log_loading import DEFAULT_PATTERNS, JointLog, load_joint_log, reduce_joint_log
from robocal.dynamics.log_parts import LogPart, within
from robocal.dynamics.motor_log import DEFAULT_PATTERNS as MOTOR_PATTERNS, MotorLog, load_motor_log
from robocal.dynamics.plausible_bounds import body_bounds
from robocal.dynamics.reduced_model import reduced_model, velocity_index
from robocal.dynamics.urdf_checks import check_urdf_inertials, massless_body_notes, moving_links
from robocal.errors import InputError
from robocal.workflows.identify_config import IdentifyConfig, LogSpec, load_identify_config


def identify_from_config(path_or_dict, base_dir=None) -> IdentifyResult:
    """Run the whole identification described by a YAML file or mapping (see identify_config.py); the
    result's `config` is the whole IdentifyConfig."""
    cfg = load_identify_config(path_or_dict, base_dir)
    if not Path(cfg.urdf).is_file():
        raise InputError("URDF file not found", source=str(cfg.urdf), field="robot.urdf")
    urdf_text = Path(cfg.urdf).read_text(encoding="utf-8")
    check_urdf_inertials(urdf_text, str(cfg.urdf))            # non-finite values refused before Pinocchio reads them
    model = reduced_model(cfg.urdf, cfg.joints)
    notes = check_urdf_inertials(urdf_text, str(cfg.urdf), moving_links(model)) + massless_body_notes(model)
    if cfg.transmission is not None:
        channels = Channels.of_motors(model, cfg.transmission, cfg.recorded, cfg.motor_terms)
        parts = [motor_part(cfg, spec, model, channels.names) for spec in cfg.logs]
        check_motion(cfg, parts, [cfg.joints.index(model.names[j]) for j in range(1, model.njoints)
                                  if model.joints[j].idx_v in channels.term_joints()])
    else:
        recorded = sorted(cfg.recorded, key=lambda j: velocity_index(model, j))
        channels = Channels.of_joints(model, recorded)
        rec_cols = [cfg.joints.index(j) for j in recorded]
        effort_map = effort_map_of(cfg, recorded)
        parts = []
        for spec in cfg.logs:
            log = load_joint_log({k: str(p) for k, p in spec.files.items()}, cfg.joints, spec.time_column,
                                 spec.patterns, spec.sample_period)
            check_windows(cfg, spec, log)
            check_limits(spec, log, model, cfg.joints)
            check_efforts(spec, log, rec_cols, recorded)
            notes += [f"{spec.name}: effort column '{c}' is for a joint not in robot.joints: ignored"
                      for c in log.unused_efforts]
            log, raw, choices = reduce_joint_log(log, cfg.signal.max_rate_hz)       # kHz logs
            parts.append(LogPart(log, effort_map.torques(log.effort[:, rec_cols]), spec.train, spec.validate,
                                 spec.name, None if raw is None else effort_map.torques(raw[:, rec_cols]), choices))
        check_motion(cfg, parts, rec_cols)
    bounds = (body_bounds(model, urdf_text, cfg.mass_ratio, cfg.margin_m, cfg.ellipsoids) if cfg.plausible else None)
    return identify_log(model, parts, channels.names, cfg, bounds, notes, channels)


def effort_map_of(cfg: IdentifyConfig, recorded: list[str]) -> EffortMap:
    """Efforts to the channels' torques: gear ratio x motor constant + offset per recorded joint, or the
    torque constant per logged motor (1 for motor torques)."""
    if cfg.transmission is not None:
        return EffortMap(recorded, cfg.transmission.motor_torques(np.ones((1, len(recorded))), recorded)[0],
                         np.zeros(len(recorded)))
    return EffortMap(recorded, np.array([cfg.torque_scale[j] for j in recorded]),
                     np.array([cfg.torque_offset.get(j, 0.0) for j in recorded]))


def read_motor_log(spec, transmission, logged: list[str], max_rate_hz: float) -> MotorLog:
    return load_motor_log({k: str(p) for k, p in spec.files.items()}, transmission.motors, logged, spec.time_column,
                          spec.sample_period, spec.patterns, max_rate_hz)


def motor_part(cfg: IdentifyConfig, spec: LogSpec, model: pin.Model, logged: list[str]) -> LogPart:
    """A motor-side log as a LogPart: joint positions through the transmission (no velocities), the logged
    motors' torques, the raw readings at the kept rows; checked like a joint log."""
    tr = cfg.transmission
    mlog = read_motor_log(spec, tr, logged, cfg.signal.max_rate_hz)
    log = JointLog(mlog.t, tr.joint_positions(mlog.position), None, mlog.effort, list(tr.joints), mlog.files)
    check_windows(cfg, spec, log)
    check_limits(spec, log, model, tr.joints, mlog.lines)
    for k, motor in enumerate(logged):
        if not np.any(mlog.effort_raw[:, k]):
            raise InputError("the effort is zero throughout: not logged? (leave the motor out of effort.recorded)",
                             source=mlog.files["effort"], field=_column(spec, "effort", motor, MOTOR_PATTERNS))
    return LogPart(log, tr.motor_torques(mlog.effort, logged), spec.train, spec.validate, spec.name,
                   tr.motor_torques(mlog.effort_raw, logged), mlog.choices)


def check_windows(cfg: IdentifyConfig, spec: LogSpec, log: JointLog) -> None:
    for key in ("train", "validate"):
        for a, b in getattr(spec, key):
            if a < log.t[0] or b > log.t[-1] + 1.0:
                raise InputError(f"{spec.name}: window [{a}, {b}] s lies outside the log ({log.t[0]:.4g} to "
                                 f"{log.t[-1]:.4g} s)", source=cfg.source, field=f"windows.{key}")


def check_efforts(spec: LogSpec, log: JointLog, rec_cols: list[int], recorded: list[str]) -> None:
    """A recorded joint whose effort column is zero throughout was not logged."""
    for k, name in zip(rec_cols, recorded):
        if not np.any(log.effort[:, k]):
            raise InputError("the effort is zero throughout: not logged? (leave the joint out of effort.recorded)",
                             source=log.files["effort"], field=_column(spec, "effort", name))


def check_motion(cfg: IdentifyConfig, parts: list[LogPart], rec_cols: list[int]) -> None:
    """A recorded joint that does not move in any training window cannot be identified."""
    for k in rec_cols:
        spans = [float(np.ptp(p.log.q[within(p.log.t, p.train), k])) if within(p.log.t, p.train).any() else 0.0
                 for p in parts]
        if max(spans) < cfg.min_motion:
            spec = cfg.logs[int(np.argmax(spans))]
            raise InputError(f"joint moves by {max(spans):.3g} (< windows.min_motion = {cfg.min_motion:g}) in the "
                             f"training windows {[list(w) for w in spec.train]} s: the trajectory does not excite it",
                             source=parts[cfg.logs.index(spec)].log.files["position"],
                             field=_column(spec, "position", cfg.joints[k]) if cfg.transmission is None else
                             f"{cfg.joints[k]} (from the motors through the transmission)")


def _column(spec: LogSpec, kind: str, joint: str, defaults: dict = DEFAULT_PATTERNS) -> str:
    """The file's column of `joint` (or motor: the config's pattern, else the loader's default)."""
    return {**defaults, **spec.patterns}[kind].format(joint=joint, motor=joint)


LIMIT_MARGIN = 0.05     # of the joint's range: encoders overshoot a soft limit a little, degrees by 57x


def check_limits(spec: LogSpec, log: JointLog, model: pin.Model, joints: list[str],
                 lines: np.ndarray | None = None) -> None:
    """A position far outside the URDF's joint limits is a unit or column mix-up (degrees, millimetres, a
    joint's column swapped), not motion: said with its file, row and column before anything is fitted.
    lines: the file line of each row of a motor-side log (its joint positions come through the transmission)."""
    for k, name in enumerate(joints):
        joint = model.joints[model.getJointId(name)]
        if joint.nq != 1:
            continue
        lo, hi = model.lowerPositionLimit[joint.idx_q], model.upperPositionLimit[joint.idx_q]
        if not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
            continue
        margin = LIMIT_MARGIN * (hi - lo)
        outside = np.flatnonzero((log.q[:, k] < lo - margin) | (log.q[:, k] > hi + margin))
        if len(outside):
            i = int(outside[0])
            if lines is not None:
                raise InputError(f"{name}'s position {log.q[i, k]:.6g} from the motors (q = T m + c) is outside its "
                                 f"limits [{lo:.4g}, {hi:.4g}] of the URDF ({len(outside)} rows in all): check the "
                                 "transmission's ratios, signs and offsets, and the encoder units",
                                 source=log.files["position"], row=int(lines[i]), field="transmission")
            raise InputError(f"position {log.q[i, k]:.6g} is outside the joint's limits [{lo:.4g}, {hi:.4g}] of the "
                             f"URDF ({len(outside)} rows in all): degrees or millimetres instead of radians or "
                             "metres, or another joint's column?", source=log.files["position"], row=i + 2,
                             field=_column(spec, "position", name))
