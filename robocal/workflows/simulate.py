"""`robocal simulate`: a synthetic dataset and its truth, from the same YAML as a calibration.

The config's `simulation` section says how many samples, which seed, how large the true parameter
errors are, and (optionally) the true values of set-up quantities:

    simulation:
      seed: 1
      samples: 60                      # rows shared by all observed blocks (pose, point, ball bar ...)
      perturb: {translation: 0.002, rotation: 0.0035}   # uniform +- bounds, m and rad
      truth: {plane0.offset: 0.412}    # true set-up values (default: the config's initial values)

Contact blocks (plane, sphere, cylinder, laser line) get their own rows (`samples:` in the block,
default 20), marked in a `block` column with the block's name; observed rows are marked `observed`.
The CSV goes to the config's data.csv (or -o), in the config's `data.units` and `data.joint_units`, and
the truth (SI) to `<csv stem>_truth.json` beside it.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from robocal.errors import InputError
from robocal.residuals import REGISTRY
from robocal.workflows.config_camera import refuse_camera_blocks
from robocal.workflows.config_read import read_config
from robocal.workflows.config_sections import is_prismatic
from robocal.workflows.config_types import SimulationConfig
from robocal.workflows.setup import build_robot, build_setup, joint_columns
from robocal.io.tables import ANGLE_UNITS, LENGTH_UNITS, Table, write_csv
from robocal.io.text_files import write_atomic

QUAT_W = 6  # position of qw in a pose block's columns


def simulate_dataset(config: str | Path, output: str | Path | None = None, seed: int | None = None,
                     force: bool = False) -> list[Path]:
    """Write the synthetic CSV (in the config's data units) and its truth JSON; returns both paths."""
    config = read_config(config)
    refuse_camera_blocks(config, "simulate", "it writes one CSV, and a camera's corners go to a detections file; "
                         "simulate them with robocal.design.simulate_detections (examples/camera/simulate_data.py)")
    sim = config.simulation or SimulationConfig()
    seed = sim.seed if seed is None else seed
    rng = np.random.default_rng(seed)
    out, truth_path = output_files(config, output, force)
    robot = build_robot(config.robot, config.source)
    labels, block_label, counts = block_rows_wanted(config, sim)
    joint_cols = joint_columns(config.data, robot, config.frames, config.source)
    joint_scale = [_unit_factor("length" if is_prismatic(robot, j) else "angle", config.data.joint_units.as_dict())
                   for j in joint_cols]
    table, block_col = provisional_table(config, robot, joint_cols, joint_scale, counts, out, rng)
    block_rows = [np.flatnonzero(block_col == labels.index(lab)) for lab in block_label]
    setup = build_setup(config, table=table, block_rows=block_rows)
    truth = perturb(setup.problem.params, rng, sim.translation, sim.rotation)
    try:
        truth.set_values(sim.truth)
    except InputError as exc:
        raise InputError(exc.reason, source=config.source, field="simulation.truth") from None
    simulate_measurements(setup.problem, truth, rng)
    final = gathered_columns(setup, joint_scale, len(block_col))
    final["block"] = block_col
    out.parent.mkdir(parents=True, exist_ok=True)
    write_csv(out, final)
    truth_doc = {"seed": seed, "block_labels": labels, "parameters": {p.name: p.value for p in truth}}
    write_atomic(truth_path, (json.dumps(truth_doc, indent=2) + "\n").encode())
    return [out, truth_path]


def output_files(config, output, force: bool) -> tuple[Path, Path]:
    """(the CSV, its truth JSON): -o, else the config's data.csv; refused if they exist without force."""
    if output is None and config.data.csv is None:
        raise InputError("required key is missing", source=config.source, field="data.csv")
    out = Path(output).resolve() if output else config.data.csv
    truth_path = out.with_name(out.stem + "_truth.json")
    for p in (out, truth_path):
        if p.exists() and not force:
            raise InputError("file exists; pass --force to replace it", source=str(p))
    return out, truth_path


def block_rows_wanted(config, sim) -> tuple[list[str], list[str], list[int]]:
    """(row-group labels, each block's label, rows per group): the observed blocks share `sim.samples` rows
    ('observed'); each contact block has its own (`samples:`, default 20), labelled with its name."""
    labels, block_label, counts = [], [], []
    for m in config.measurements:
        observed = REGISTRY[m.type].observed
        label = "observed" if observed else m.name
        block_label.append(label)
        if label not in labels:
            labels.append(label)
            counts.append(sim.samples if observed else m.samples or 20)
    return labels, block_label, counts


def provisional_table(config, robot, joint_cols, joint_scale, counts, out: Path, rng):
    """(table, each row's group): random readings and placeholder measurements in the config's units; the real
    values come from the truth."""
    n_total = sum(counts)
    q = random_configurations(robot, list(joint_cols), n_total, rng, span=0.9)
    cols = {c: q[:, k] / joint_scale[k] for k, c in enumerate(joint_cols.values())}
    block_col = np.concatenate([[idx] * n for idx, n in enumerate(counts)])
    for m in config.measurements:
        for c in m.columns:
            cols[c] = np.zeros(n_total)
        if m.type == "pose" and len(m.columns) > QUAT_W:
            cols[m.columns[QUAT_W]] = np.ones(n_total)
    return Table.from_columns(out, {**cols, "block": block_col}), block_col


def gathered_columns(setup, joint_scale, n_total: int) -> dict[str, np.ndarray]:
    """Every sample written back to the provisional row it came from, in the config's units."""
    problem, units = setup.problem, setup.units
    rows = np.array([r for _, r in setup.sample_rows], dtype=int)
    final = {}
    for k, j in enumerate(problem.joint_names):
        v = np.zeros(n_total)
        v[rows] = problem.values[:, k] / joint_scale[k]
        final[setup.joint_columns[j]] = v
    for res in problem.residuals:
        kinds = type(res).column_kinds(len(res.columns))
        for c, column in enumerate(res.columns):
            v = final.setdefault(column, np.zeros(n_total))
            v[rows[res.samples]] = res.measurements[:, c] / _unit_factor(kinds[c], units)
    return final


def _unit_factor(kind: str, units: dict[str, str]) -> float:
    """SI value of one unit of `kind` ('length', 'angle' or '' for unitless)."""
    return {"length": LENGTH_UNITS, "angle": ANGLE_UNITS}[kind][units[kind]] if kind else 1.0
