"""`robocal identify dyn.yaml`: read the config and the log, check them, identify, and return the result.

The identification itself is robocal.dynamics.identify_log; identify_outputs.py writes the folder.
See docs/dynamics_tiago.md.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.dynamics.identify_log import IdentifyResult, identify_log
from robocal.dynamics.log_loading import DEFAULT_PATTERNS, JointLog, load_joint_log
from robocal.dynamics.reduced_model import reduced_model, velocity_index
from robocal.errors import InputError
from robocal.workflows.identify_config import IdentifyConfig, load_identify_config


def identify_from_config(path_or_dict, base_dir=None) -> IdentifyResult:
    """Run the whole identification described by a YAML file or mapping (see identify_config.py); the
    result's `config` is the whole IdentifyConfig."""
    cfg = load_identify_config(path_or_dict, base_dir)
    model = reduced_model(cfg.urdf, cfg.joints)
    log = load_joint_log({k: str(p) for k, p in cfg.files.items()}, cfg.joints, cfg.time_column, cfg.patterns)
    recorded = sorted(cfg.recorded, key=lambda j: velocity_index(model, j))
    rec_cols = [cfg.joints.index(j) for j in recorded]
    check_windows(cfg, log)
    check_motion(cfg, log, rec_cols)
    check_limits(cfg, log, model)
    scale = np.array([cfg.torque_scale[j] for j in recorded])
    offset = np.array([cfg.torque_offset.get(j, 0.0) for j in recorded])
    return identify_log(model, log, recorded, log.effort[:, rec_cols] * scale + offset, cfg)


def check_windows(cfg: IdentifyConfig, log: JointLog) -> None:
    for key, (a, b) in (("train", cfg.train), ("validate", cfg.validate)):
        if a < log.t[0] or b > log.t[-1] + 1.0:
            raise InputError(f"window [{a}, {b}] s lies outside the log ({log.t[0]:.4g} to {log.t[-1]:.4g} s)",
                             source=cfg.source, field=f"windows.{key}")

def check_motion(cfg: IdentifyConfig, log: JointLog, rec_cols: list[int]) -> None:
    """A recorded joint that does not move in the training window cannot be identified."""
    mask = log.window(*cfg.train)
    for k in rec_cols:
        span = float(np.ptp(log.q[mask, k]))
        if span < cfg.min_motion:
            raise InputError(f"joint moves by {span:.3g} (< windows.min_motion = {cfg.min_motion:g}) in the "
                             f"training window {list(cfg.train)} s: the trajectory does not excite it",
                             source=log.files["position"], field=_position_column(cfg, cfg.joints[k]))

def _position_column(cfg: IdentifyConfig, joint: str) -> str:
    """The position file's column of `joint` (the config's pattern, else the loader's default)."""
    return {**DEFAULT_PATTERNS, **cfg.patterns}["position"].format(joint=joint)

LIMIT_MARGIN = 0.05     # of the joint's range: encoders overshoot a soft limit a little, degrees by 57x

def check_limits(cfg: IdentifyConfig, log: JointLog, model: pin.Model) -> None:
    """A position far outside the URDF's joint limits is a unit or column mix-up (degrees, millimetres, a
    joint's column swapped), not motion: said with its file, row and column before anything is fitted."""
    for k, name in enumerate(cfg.joints):
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
            raise InputError(f"position {log.q[i, k]:.6g} is outside the joint's limits [{lo:.4g}, {hi:.4g}] of the "
                             f"URDF ({len(outside)} rows in all): degrees or millimetres instead of radians or "
                             "metres, or another joint's column?", source=log.files["position"], row=i + 2,
                             field=_position_column(cfg, name))
