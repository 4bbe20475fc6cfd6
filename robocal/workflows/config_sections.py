"""The `parameters:`, `data.approach` and `solver:` sections of the calibration YAML (docs/config.md).

Called by robocal.workflows.config.setup_from_config; every mistake names the file and the key path.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError
from robocal.estimation.calibrate import CalibrationOptions
from robocal.workflows.config_keys import Cfg
from robocal.io.tables import Table
from robocal.model.approach import ApproachSpec, table_directions
from robocal.model.parameters import COMPONENTS, ParameterSet, robot_parameters


def is_prismatic(robot, joint: str) -> bool:
    return robot.model.joints[robot.joint_id(joint)].shortname().startswith("JointModelP")


def joint_values(robot, tab: Table, joint_cols: dict[str, str], rows, joint_units: dict[str, str]) -> np.ndarray:
    """(len(rows), n_joints) readings in SI; joint_units: {'length': unit, 'angle': unit}."""
    cols = []
    for j, c in joint_cols.items():
        kind = "length" if is_prismatic(robot, j) else "angle"
        cols.append(tab.column(c, kind, joint_units[kind], rows))
    return np.column_stack(cols) if cols else np.zeros((len(rows), 0))


def parameters_from_config(cfg: Cfg, robot, chain: list[str]) -> ParameterSet:
    """The parameter set of the `parameters:` section; chain: the joints moving a measured frame."""
    if cfg.value is None:
        cfg = Cfg({}, cfg.path, cfg.source)
    cfg.require_mapping()
    joints = cfg.get("joints", chain, types=list)
    frames_sel = {}
    for name, v in cfg.get("frames", {}, types=dict).items():
        if v is not True and v is not False and not (isinstance(v, list) and set(map(str, v)) <= set(COMPONENTS)):
            raise cfg.child("frames").error(f"expected true or a list of {', '.join(COMPONENTS)}, got {v!r}", str(name))
        if v:
            frames_sel[str(name)] = True if v is True else [str(c) for c in v]
    base = cfg.get("base", False, types=(bool, list))
    if isinstance(base, list) and not set(map(str, base)) <= set(COMPONENTS):
        raise cfg.error(f"expected true or a list of {', '.join(COMPONENTS)}, got {base!r}", "base")
    try:
        return robot_parameters(robot, [str(j) for j in joints], cfg.get("preset", "full", types=str),
                                frames_sel, base, cfg.get("compliance", False, types=(bool, list)),
                                cfg.get("backlash", False, types=(bool, list)),
                                cfg.get("tilt", False, types=(bool, list)))
    except InputError as exc:
        raise cfg.error(exc.reason) from None


def approach_spec(cfg: Cfg, joint_names) -> ApproachSpec:
    spec = ApproachSpec(source=cfg.get("from", "order", types=str), sort_by=cfg.get("sort_by", types=str))
    if spec.source not in ("order", "columns"):
        raise cfg.error(f"unknown source '{spec.source}' (order, columns)", "from")
    th = cfg.child("threshold", {})
    th.require_mapping()
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


def approach_directions(cfg: Cfg, pcfg: Cfg, params: ParameterSet, robot, tables, samples, joint_cols,
                        joint_units):
    """(N, n_joints) approach directions of the samples, or None without a data.approach section."""
    backlash = [p.target for p in params if p.kind == "joint_backlash"]
    if cfg.value is None:
        if backlash:
            raise pcfg.error("backlash needs the approach direction of every sample: add data.approach "
                             "(docs/config.md)", "backlash")
        return None
    cfg.require_mapping()
    joints = list(joint_cols)
    spec = approach_spec(cfg, joints)
    if spec.source == "columns":
        missing = [j for j in backlash if j not in spec.columns]
        if missing:
            raise cfg.error(f"joint '{missing[0]}' has a backlash parameter but no direction column", "columns")
    prismatic = [is_prismatic(robot, j) for j in joints]
    out = np.zeros((len(samples), len(joints)))
    for file in dict.fromkeys(f for f, _ in samples):
        tab = tables[file]
        rows = np.arange(tab.n_rows)
        per_row = table_directions(tab, joint_values(robot, tab, joint_cols, rows, joint_units), joints,
                                   prismatic, spec)
        for (f, r), i in samples.items():
            if f == file:
                out[i] = per_row[r]
    return out


def apply_parameter_overrides(cfg: Cfg, params: ParameterSet) -> None:
    """fix / free / initial / priors / bounds of the `parameters:` section (values in SI, m and rad)."""
    if cfg.value is None:
        return
    try:
        params.fix(*cfg.get("fix", [], types=list))
        params.free(*cfg.get("free", [], types=list))
        for pat, v in cfg.get("initial", {}, types=dict).items():
            for n in params.select(pat):
                params[n].value = float(v)
        for pat, sigma in cfg.get("priors", {}, types=dict).items():
            if not float(sigma) > 0:
                raise cfg.child("priors").error(f"a prior sigma must be positive, got {sigma!r}", str(pat))
            for n in params.select(pat):
                params[n].prior_sigma, params[n].prior_mean = float(sigma), params[n].value
        for pat, bound in cfg.get("bounds", {}, types=dict).items():
            if not (isinstance(bound, list) and len(bound) == 2):
                raise cfg.child("bounds").error(f"expected [low, high], got {bound!r}", str(pat))
            lo, hi = bound
            for n in params.select(pat):
                params[n].min = -np.inf if lo is None else float(lo)
                params[n].max = np.inf if hi is None else float(hi)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, InputError) and exc.field:
            raise
        raise cfg.error(getattr(exc, "reason", str(exc))) from None


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
