"""Plausibility of a setup's data before any fit: units, and readings the machine can take.

A units mix-up (metres declared as mm, or the reverse) scales every measured position by 1000. The
check compares how far the measured positions of each block spread about their centroid with how far
the nominal model's predictions of the same points spread. The spread does not change under the rigid
placement of the measurement frame, which the config usually lets float (`parameters.base`), so no
registration is needed; a nominal model off by millimetres changes it by percent, a units mix-up by
a factor of 1000. Closed chains: every sample's readings must assemble on the nominal model; an
unreachable one is named by file and row. See docs/config.md, "Units".
"""
from __future__ import annotations

import numpy as np

from robocal.errors import AssemblyError, InputError
from robocal.io.tables import LENGTH_UNITS
from robocal.model.kinematics import ModelState

#: measured / model spread beyond this factor (either way) is a units problem: a genuine model error
#: changes the spread by percent, a mm/m mix-up by 1000; 30 sits in between on a log scale
SCALE_LIMIT = 30.0
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


def _hint(ratio: float, unit: str) -> str:
    for other, factor in LENGTH_UNITS.items():
        implied = ratio * factor / LENGTH_UNITS[unit]   # the spread ratio had the data been read in `other`
        if other != unit and 1 / SCALE_LIMIT < implied < SCALE_LIMIT:
            words = {"m": "metres", "mm": "millimetres"}
            return f"the data look like {words[other]}; the config says {unit} (data.units.length)"
    return "check data.units and the robot model"


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
    measure positions (pose, point, rigid_points) or lengths (ball_bar) and whose points the model moves."""
    problem = setup.problem
    states = nominal_states(setup) if states is None else states
    values = {p.name: p.value for p in problem.params}
    out = {}
    for res in problem.residuals:
        if res.type_name not in ("pose", "point", "rigid_points", "ball_bar") or res.n_terms < 2:
            continue
        aux = [values.get(p.name, p.value) for p in res.aux_parameters()]
        terms = np.unique(np.linspace(0, res.n_terms - 1, min(res.n_terms, MAX_SAMPLES)).astype(int))
        model = np.vstack([_model_points(res, states[int(res.samples[k])], aux) for k in terms])
        measured = np.vstack([_measured_points(res, res.measurements[k]) for k in terms])
        s_model, s_meas = _spread(model), _spread(measured)
        if s_model >= 1e-6:          # else the model does not move the points: nothing to compare
            out[res.name] = (s_meas / s_model, s_meas, s_model)
    return out


def units_findings(setup, states=None) -> list[InputError]:
    """One InputError per block whose measured positions spread implausibly far from the model's."""
    findings = []
    blocks = {r.name: r for r in setup.problem.residuals}
    for name, (ratio, s_meas, s_model) in spread_ratios(setup, states).items():
        if 1 / SCALE_LIMIT < ratio < SCALE_LIMIT:
            continue
        res = blocks[name]
        what = "bar lengths are" if res.type_name == "ball_bar" else "positions spread"
        cols = ", ".join(res.columns[:3]) + (" ..." if len(res.columns) > 3 else "")
        files = sorted({setup.sample_rows[int(i)][0] for i in np.unique(res.samples)})
        findings.append(InputError(
            f"block '{name}' (columns {cols} of {', '.join(files)}): the measured {what} {ratio:.3g} times "
            f"the nominal model's ({s_meas * 1e3:.4g} mm against {s_model * 1e3:.4g} mm, read in "
            f"{setup.units['length']}); {_hint(ratio, setup.units['length'])}",
            source=setup.source or str(setup.config_path), field="data.units.length"))
    return findings
