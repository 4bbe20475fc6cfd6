"""Joint readings against the robot: each joint read from a column of its own, each reading within the
URDF's limits.

Limits rule (docs/config.md, "Bad input"): a reading may lie beyond a URDF limit by up to LIMIT_MARGIN of
the joint's range (URDF limits are often the controller's soft limits, and the TIAGo's torso reads 0.2 mm
past its upper limit); further out, the column, its unit (data.joint_units) or the URDF is wrong, and the
first such reading is named by file, row and column. Joints without finite limits (continuous) are not
checked.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError
from robocal.workflows.config_sections import is_prismatic

#: how far beyond a URDF limit a reading may lie, as a fraction of the joint's range (upper - lower)
LIMIT_MARGIN = 0.1


def check_joint_columns(cols: dict[str, str], source: str) -> None:
    """Refuse two joints read from one CSV column (data.joints): each joint has its own reading."""
    by_column: dict[str, list[str]] = {}
    for joint, column in cols.items():
        by_column.setdefault(column, []).append(joint)
    for column, joints in by_column.items():
        if len(joints) > 1:
            raise InputError(f"joints {', '.join(repr(j) for j in joints)} are all read from column '{column}'; "
                             "each joint needs its own column (data.joints: {joint: column})", source=source,
                             field="data.joints")


def limit_findings(setup) -> list[InputError]:
    """One InputError per joint with a reading beyond its URDF limits by more than LIMIT_MARGIN of its range,
    naming the first such row."""
    robot, problem = setup.robot, setup.problem
    model = robot.model
    findings = []
    for c, joint in enumerate(problem.joint_names):
        jm = model.joints[robot.joint_id(joint)]
        if jm.nq != 1:
            continue
        lo, hi = model.lowerPositionLimit[jm.idx_q], model.upperPositionLimit[jm.idx_q]
        if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
            continue
        margin = LIMIT_MARGIN * (hi - lo)
        v = problem.values[:, c]
        beyond = np.flatnonzero((v < lo - margin) | (v > hi + margin))
        if not len(beyond):
            continue
        i = int(beyond[0])
        file, row = setup.sample_rows[i]
        unit = "m" if is_prismatic(robot, joint) else "rad"
        column = setup.joint_columns.get(joint, joint)
        others = f" ({len(beyond)} of its readings are)" if len(beyond) > 1 else ""
        findings.append(InputError(
            f"joint '{joint}' reads {v[i]:.6g} {unit}, beyond its URDF limits [{lo:.6g}, {hi:.6g}] {unit} by more "
            f"than the margin of {LIMIT_MARGIN:.0%} of its range ({margin:.4g} {unit}){others}; check the column "
            "(data.joints), its unit (data.joint_units) and the URDF", source=file,
            row=setup.tables[file].line(row) if file in setup.tables else None, field=column))
    return findings
