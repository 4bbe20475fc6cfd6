"""Plausibility of a setup's data before any fit: units, and readings the machine can take.

A units mix-up (metres declared as mm, or the reverse) scales every measured position by 1000. The
check compares how far the measured positions of each block spread about their centroid with how far
the nominal model's predictions of the same points spread. The spread does not change under the rigid
placement of the measurement frame, which the config usually lets float (`parameters.base`), so no
registration is needed; a nominal model off by millimetres changes it by percent, a units mix-up by
a factor of 1000 (m / mm), 100 (m / cm), 39.4 (m / inch), 25.4 (mm / inch) or 10 (mm / cm).

The rule (docs/config.md, "Units"): a block whose measured / model spread lies within a factor ACCEPT of 1
passes. Otherwise each other reading is tried - the positions in another length unit (m, cm, mm, in), the
joint angles in the other angle unit, prismatic joints in another length unit - and the one that brings
the spread ratio nearest 1, within ACCEPT, is named as the suspected unit and the data are refused. A
ratio beyond SCALE_LIMIT that no reading explains is refused too ("check data.units and the robot
model"). Closed chains: every sample's readings must assemble on the nominal model; an unreachable one
is named by file and row.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import AssemblyError, InputError
from robocal.io.tables import ANGLE_UNITS, LENGTH_UNITS
from robocal.model.kinematics import ModelState
from robocal.workflows.config_sections import is_prismatic

#: measured / model spread beyond this factor (either way) is a units problem: a genuine model error
#: changes the spread by percent, a mm/m mix-up by 1000; 30 sits in between on a log scale
SCALE_LIMIT = 30.0
#: measured / model spread within this factor of 1 is right, and a reading that brings it there explains it:
#: the shipped examples give 0.995 (the UR5 demo), 1.15 and 1.25 (TIAGo's point and hand blocks, whose points
#: start at their frame's origin); the nearest unit factor is 2.54 (cm / inch), the next 10 (mm / cm)
ACCEPT = 1.5
#: the words for each length unit in a message
UNIT_WORDS = {"m": "metres", "cm": "centimetres", "mm": "millimetres", "in": "inches", "rad": "radians",
              "deg": "degrees"}
#: samples used for the spread (evenly spaced): enough for a stable RMS, cheap on any dataset
MAX_SAMPLES = 200


def _model_points(res, state, aux) -> np.ndarray | None:
    """(k, 3) points the block measures at one sample, predicted by the nominal model (None: no positions)."""
    M = state.pose(res.frame)
    if res.type_name == "pose":
        return M.translation[None, :]
    if res.type_name == "point":
        return M.act(np.asarray(aux[:3]))[None, :]
    if res.type_name == "rigid_points":
        return np.array([M.act(np.asarray(aux[3 * i:3 * i + 3])) for i in range(len(aux) // 3)])
    if res.type_name == "ball_bar":
        return np.array([[np.linalg.norm(M.act(np.asarray(aux[4:7])) - np.asarray(aux[:3]))]])
    return None


def _measured_points(res, row: np.ndarray) -> np.ndarray:
    if res.type_name == "pose":
        return row[None, :3]
    if res.type_name == "ball_bar":
        return row[None, :1]
    return row.reshape(-1, 3)


def _spread(points: np.ndarray) -> float:
    """RMS distance of the points from their centroid (ball bar: RMS length)."""
    if points.shape[1] == 1:
        return float(np.sqrt(np.mean(points ** 2)))
    return float(np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1))))


def nominal_states(setup) -> list:
    """The nominal model's state at every sample; a closed chain that cannot assemble is named by row."""
    problem = setup.problem
    ms = ModelState(setup.robot, problem.params, problem.joint_names)
    states = []
    for i, v in enumerate(problem.values):
        try:
            states.append(ms.sample(v, label=i))
        except AssemblyError as exc:
            file, row = setup.sample_rows[i]
            table = setup.tables[file]
            raise InputError(f"the nominal machine cannot take these readings ({exc}); check the readings and "
                             "data.joint_units",
                             source=file, row=table.line(row),
                             field=", ".join(setup.joint_columns.values())) from None
    return states


def spread_ratios(setup, states=None) -> dict[str, tuple[float, float, float]]:
    """{block name: (measured / model spread, measured spread m, model spread m)} of the blocks that
    measure positions (pose, point, rigid_points) or lengths (ball_bar) and whose points the model moves.
    states: the nominal model's state at each sample (a list, or a dict of the sampled ones)."""
    problem = setup.problem
    states = nominal_states(setup) if states is None else states
    values = {p.name: p.value for p in problem.params}
    out = {}
    for res, terms in sampled_terms(setup):
        aux = [values.get(p.name, p.value) for p in res.aux_parameters()]
        model = np.vstack([_model_points(res, states[int(res.samples[k])], aux) for k in terms])
        measured = np.vstack([_measured_points(res, res.measurements[k]) for k in terms])
        s_model, s_meas = _spread(model), _spread(measured)
        if s_model >= 1e-6:          # else the model does not move the points: nothing to compare
            out[res.name] = (s_meas / s_model, s_meas, s_model)
    return out


def sampled_terms(setup):
    """(residual, the terms the spread uses: evenly spaced, at most MAX_SAMPLES) of the position blocks."""
    for res in setup.problem.residuals:
        if res.type_name in ("pose", "point", "rigid_points", "ball_bar") and res.n_terms >= 2:
            yield res, np.unique(np.linspace(0, res.n_terms - 1, min(res.n_terms, MAX_SAMPLES)).astype(int))


def joint_reading_ratios(setup) -> dict[tuple[str, str], dict[str, float]]:
    """{(joint kind, other unit): {block: spread ratio}} with the joint readings of that kind read in the other
    unit instead of data.joint_units (the sampled postures only; a closed chain that cannot assemble so is
    left out)."""
    problem = setup.problem
    prismatic = np.array([is_prismatic(setup.robot, j) for j in problem.joint_names], dtype=bool)
    needed = sorted({int(res.samples[k]) for res, terms in sampled_terms(setup) for k in terms})
    out = {}
    for kind, table, mask in (("angle", ANGLE_UNITS, ~prismatic), ("length", LENGTH_UNITS, prismatic)):
        declared = setup.joint_units[kind]
        if not mask.any():
            continue
        for other, factor in table.items():
            if other == declared:
                continue
            scale = np.where(mask, factor / table[declared], 1.0)
            ms = ModelState(setup.robot, problem.params, problem.joint_names)
            try:
                states = {i: ms.sample(problem.values[i] * scale, label=i) for i in needed}
            except AssemblyError:
                continue
            out[(kind, other)] = {name: r for name, (r, _, _) in spread_ratios(setup, states).items()}
    return out


def explanation(ratio: float, unit: str, joint_ratios: dict) -> tuple[float, str, str] | None:
    """(ratio once explained, what the data look like, the key to change) of the other reading that brings a
    block's spread ratio nearest 1 within ACCEPT; None when none does."""
    options = [(ratio * factor / LENGTH_UNITS[unit], f"the data look like {UNIT_WORDS[other]}; the config says "
                f"{unit} (data.units.length: {other})", "data.units.length")
               for other, factor in LENGTH_UNITS.items() if other != unit]
    options += [(r, f"the joint readings look like {UNIT_WORDS[other]}; the config says "
                 f"{declared} (data.joint_units.{kind}: {other})", f"data.joint_units.{kind}")
                for (kind, other, declared), r in joint_ratios]
    best = min(options, key=lambda o: abs(np.log(o[0])), default=None)
    return best if best is not None and 1 / ACCEPT < best[0] < ACCEPT else None


def units_findings(setup, states=None) -> list[InputError]:
    """One InputError per block whose measured positions spread implausibly far from the model's, naming the
    unit that explains it when one does (the module docstring's rule)."""
    findings = []
    blocks = {r.name: r for r in setup.problem.residuals}
    ratios = spread_ratios(setup, states)
    off = {name: v for name, v in ratios.items() if not 1 / ACCEPT < v[0] < ACCEPT}
    joint = joint_reading_ratios(setup) if off else {}
    for name, (ratio, s_meas, s_model) in off.items():
        res = blocks[name]
        unit = setup.units["length"]
        alternatives = [((kind, other, setup.joint_units[kind]), by_block[name])
                        for (kind, other), by_block in joint.items() if name in by_block]
        found = explanation(ratio, unit, alternatives)
        if found is None and 1 / SCALE_LIMIT < ratio < SCALE_LIMIT:
            continue
        hint, key = (found[1], found[2]) if found else ("check data.units and the robot model", "data.units.length")
        what = "bar lengths are" if res.type_name == "ball_bar" else "positions spread"
        cols = ", ".join(res.columns[:3]) + (" ..." if len(res.columns) > 3 else "")
        files = sorted({setup.sample_rows[int(i)][0] for i in np.unique(res.samples)})
        findings.append(InputError(
            f"block '{name}' (columns {cols} of {', '.join(files)}): the measured {what} {ratio:.3g} times "
            f"the nominal model's ({s_meas * 1e3:.4g} mm against {s_model * 1e3:.4g} mm, read in "
            f"{unit}); {hint}", source=setup.source or str(setup.config_path), field=key))
    return findings
