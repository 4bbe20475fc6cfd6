"""The set-up's parameters and approach directions from the typed `parameters:` and `data.approach` sections.

Called by robocal.workflows.setup.build_setup, once the robot and the data are known; every mistake names
the file and the key path.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError
from robocal.io.tables import Table
from robocal.model.approach import ApproachSpec, table_directions
from robocal.model.parameters import ParameterSet, robot_parameters
from robocal.workflows.config_types import ParametersConfig, Units


def is_prismatic(robot, joint: str) -> bool:
    return robot.model.joints[robot.joint_id(joint)].shortname().startswith("JointModelP")


def joint_values(robot, tab: Table, joint_cols: dict[str, str], rows, joint_units: Units) -> np.ndarray:
    """(len(rows), n_joints) readings in SI."""
    cols = []
    for j, c in joint_cols.items():
        kind = "length" if is_prismatic(robot, j) else "angle"
        cols.append(tab.column(c, kind, getattr(joint_units, kind), rows))
    return np.column_stack(cols) if cols else np.zeros((len(rows), 0))


def parameter_set(pc: ParametersConfig, robot, chain: list[str], source: str,
                  read: list[str] | None = None) -> ParameterSet:
    """The parameter set of the `parameters:` section; chain: the joints moving a measured frame; read: the
    joints the data read (a closed chain's passive joints get no offset, compliance or backlash)."""
    joints = list(pc.joints) if pc.joints is not None else chain
    frames = {name: True if v is True else list(v) for name, v in pc.frames.items() if v}
    kind = [v if isinstance(v, bool) else list(v) for v in (pc.base, pc.compliance, pc.backlash, pc.tilt)]
    try:
        return robot_parameters(robot, joints, pc.preset, frames, *kind, read=read)
    except InputError as exc:
        raise InputError(exc.reason, source=source, field="parameters" + (f".{exc.field}" if exc.field else "")) from None


def apply_parameter_overrides(pc: ParametersConfig, params: ParameterSet, source: str) -> None:
    """fix / free / initial / priors / bounds of the `parameters:` section (values in SI, m and rad)."""
    def where(key, pattern=None):
        return f"parameters.{key}" + (f".{pattern}" if pattern is not None else "")
    for key, patterns in (("fix", pc.fix), ("free", pc.free)):
        try:
            getattr(params, key)(*patterns)
        except InputError as exc:
            raise InputError(exc.reason, source=source, field=where(key)) from None
    for key, table in (("initial", pc.initial), ("priors", pc.priors), ("bounds", pc.bounds)):
        for pattern, v in table.items():
            try:
                names = params.select(pattern)
            except InputError as exc:
                raise InputError(exc.reason, source=source, field=where(key, pattern)) from None
            for n in names:
                if key == "initial":
                    params[n].value = v
                elif key == "priors":
                    params[n].prior_sigma, params[n].prior_mean = v, params[n].value
                else:
                    params[n].min = -np.inf if v[0] is None else v[0]
                    params[n].max = np.inf if v[1] is None else v[1]


def approach_directions(spec: ApproachSpec | None, params: ParameterSet, robot, tables, samples, joint_cols,
                        joint_units: Units, source: str):
    """(N, n_joints) approach directions of the samples, or None without a data.approach section."""
    backlash = [p.target for p in params if p.kind == "joint_backlash"]
    if spec is None:
        if backlash:
            raise InputError("backlash needs the approach direction of every sample: add data.approach "
                             "(docs/config.md)", source=source, field="parameters.backlash")
        return None
    joints = list(joint_cols)
    for key in ("initial", "columns"):
        unknown = [j for j in getattr(spec, key) if j not in joints]
        if unknown:
            raise InputError(f"'{unknown[0]}' is not a joint of data.joints", source=source,
                             field=f"data.approach.{key}")
    if spec.source == "columns":
        missing = [j for j in backlash if j not in spec.columns]
        if missing:
            raise InputError(f"joint '{missing[0]}' has a backlash parameter but no direction column",
                             source=source, field="data.approach.columns")
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
