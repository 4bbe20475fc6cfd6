"""Every check of a set-up's input before a fit (calibrate, cv, select, iso9283): what it refuses, what it notes.

In order: notes from reading the files (a byte-order mark stripped); sigmas that cannot be a standard
deviation (refused); repeated postures (a note) and too few distinct ones (refused, posture_check.py);
then the plausibility findings, which --allow-failed turns into warnings: units (data_check.py),
quaternion order (quaternion_check.py), readings beyond the URDF's limits (reading_check.py).
docs/config.md, "Bad input", lists every check.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError
from robocal.estimation.physical_scale import robot_size
from robocal.io.tables import ANGLE_UNITS, LENGTH_UNITS
from robocal.workflows.data_check import nominal_states, units_findings
from robocal.workflows.posture_check import check_distinct_postures, posture_counts, repeated_posture_notes
from robocal.workflows.quaternion_check import quaternion_findings
from robocal.workflows.reading_check import limit_findings


def check_inputs(setup, allow_failed: bool = False) -> list[str]:
    """Run every check; raise the first refusal (InputError), else return the notes and, with allow_failed,
    the plausibility findings as warnings, each a line for the user."""
    notes = [f"note: {n}" for t in setup.tables.values() for n in t.notes]
    check_sigma_sizes(setup)
    counts = posture_counts(setup)
    notes += [f"note: {n}" for n in repeated_posture_notes(counts)]
    check_distinct_postures(setup, counts)
    states = nominal_states(setup)
    findings = units_findings(setup, states) + quaternion_findings(setup, states) + limit_findings(setup)
    if findings and not allow_failed:
        raise findings[0]
    return notes + [f"warning: {f} (going on: --allow-failed)" for f in findings]


def check_sigma_sizes(setup) -> None:
    """Refuse a length sigma larger than the robot (the largest distance between its read joints' origins)
    and an angle sigma beyond half a turn: neither is the standard deviation of a measurement."""
    size = robot_size(setup.robot, setup.problem.joint_names)
    for block, res in zip(setup.config.measurements, setup.problem.residuals):
        for kind, limit, what in (("length", size, f"larger than the robot (its joint origins span {size:.3g} m)"),
                                  ("angle", np.pi, "beyond half a turn")):
            rows = np.array([u == kind for u in res.row_units], dtype=bool)
            if not rows.any() or res.sigma[rows].max() <= limit:
                continue
            unit = setup.units[kind]
            value = res.sigma[rows].max() / (LENGTH_UNITS if kind == "length" else ANGLE_UNITS)[unit]
            key = f"{block.path}.sigma" + ((".position" if kind == "length" else ".orientation")
                                           if isinstance(block.sigma, tuple) else "")
            raise InputError(f"a sigma of {value:g} {unit} is {what}: a sigma is the standard deviation of one "
                             "measurement; check the value and its unit", source=setup.source, field=key)
