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
The CSV goes to the config's data.csv (or -o) and the truth to `<csv stem>_truth.json` beside it.
"""
from __future__ import annotations

import copy
import json
import tempfile
from pathlib import Path

import numpy as np
import yaml

from robocal.io.config import Cfg, build_setup
from robocal.io.tables import write_csv
from robocal.errors import InputError
from robocal.io.text_files import write_atomic
from robocal.design.simulate import perturb, random_configurations, simulate_measurements

QUAT_W = 6  # position of qw in a pose block's columns


def simulate_dataset(config: str | Path, output: str | Path | None = None, seed: int | None = None,
                     force: bool = False) -> list[Path]:
    config = Path(config).resolve()
    raw = yaml.safe_load(config.read_text())
    root = Cfg(raw, "", str(config))
    sim = root.child("simulation", {})
    sim.check_keys(("seed", "samples", "perturb", "truth"))
    rng = np.random.default_rng(sim.get("seed", 0, types=int) if seed is None else seed)
    out = Path(output).resolve() if output else (config.parent / root.child("data").get("csv", required=True))
    truth_path = out.with_name(out.stem + "_truth.json")
    for p in (out, truth_path):
        if p.exists() and not force:
            raise InputError("file exists; pass --force to replace it", source=str(p))

    from robocal.residuals import REGISTRY
    from robocal.io.config import _robot

    robot = _robot(root.child("robot"), config.parent)
    blocks = root.get("measurements", required=True, types=list)
    n_obs = sim.get("samples", 60, types=int)
    rows_of, labels = [], []
    for i, b in enumerate(blocks):
        cls = REGISTRY.get(b.get("type"))
        if cls is None:
            raise InputError(f"unknown measurement type '{b.get('type')}'", source=str(config),
                             field=f"measurements[{i}].type")
        label = "observed" if cls.observed else b.get("name", f"{b['type']}{i}")
        n = n_obs if cls.observed else int(b.get("samples", 20))
        if cls.observed and "observed" in labels:
            continue
        rows_of.append((label, n))
        labels.append(label)
    # Provisional table: random readings, placeholder measurements; the real values come from the truth.
    joint_names = _joint_names(raw, robot, blocks)
    lo_span = sim.child("perturb", {})
    n_total = sum(n for _, n in rows_of)
    q = random_configurations(robot, joint_names, n_total, rng, span=0.9)
    jmap = (raw.get("data") or {}).get("joints")
    cols = {(jmap[j] if isinstance(jmap, dict) else j): q[:, k] for k, j in enumerate(joint_names)}
    block_col = np.concatenate([[idx] * n for idx, (_, n) in enumerate(rows_of)])
    meas_cols = []
    for b in blocks:
        for c in b.get("columns", []) or []:
            meas_cols.append(c)
            cols[c] = np.zeros(n_total)
    for b in blocks:
        if b.get("type") == "pose":
            cols[b["columns"][QUAT_W]] = np.ones(n_total)
    with tempfile.TemporaryDirectory() as tmp:
        tmp_csv = Path(tmp) / "provisional.csv"
        write_csv(tmp_csv, {**cols, "block": block_col})
        raw2 = copy.deepcopy(raw)
        raw2.setdefault("data", {})["csv"] = str(tmp_csv)
        for b in raw2["measurements"]:
            cls = REGISTRY[b["type"]]
            lab = "observed" if cls.observed else b.get("name", f"{b['type']}{raw2['measurements'].index(b)}")
            b["where"] = {"block": labels.index(lab)}
            b.pop("samples", None)
            b.pop("csv", None)
        raw2.pop("simulation", None)
        setup = build_setup(Cfg(raw2, "", str(config)), config.parent, raw2)
    problem = setup.problem
    truth = perturb(problem.params, rng, lo_span.get("translation", 2e-3), lo_span.get("rotation", np.radians(0.2)))
    truth.set_values(sim.get("truth", {}, types=dict))
    simulate_measurements(problem, truth, rng)
    # Gather: write every sample back to the provisional row it came from.
    rows = np.array([r for _, r in setup.sample_rows], dtype=int)
    final = {}
    for k, j in enumerate(problem.joint_names):
        v = np.zeros(n_total)
        v[rows] = problem.values[:, k]
        final[setup.joint_columns[j]] = v
    for res in problem.residuals:
        for c, column in enumerate(res.columns):
            v = final.setdefault(column, np.zeros(n_total))
            v[rows[res.samples]] = res.measurements[:, c]
    final["block"] = block_col
    out.parent.mkdir(parents=True, exist_ok=True)
    write_csv(out, final)
    truth_doc = {"seed": sim.get("seed", 0) if seed is None else seed, "block_labels": labels,
                 "parameters": {p.name: p.value for p in truth}}
    write_atomic(truth_path, (json.dumps(truth_doc, indent=2) + "\n").encode())
    return [out, truth_path]


def _joint_names(raw, robot, blocks) -> list[str]:
    joints = (raw.get("data") or {}).get("joints")
    if isinstance(joints, dict):
        return list(joints)
    if isinstance(joints, list):
        return [str(j) for j in joints]
    frames = [b["frame"] for b in blocks]
    return [j for j in robot.joint_names if any(j in robot.supporting_joints(f) for f in frames)]
