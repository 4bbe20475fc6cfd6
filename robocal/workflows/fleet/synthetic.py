"""Simulated fleets: many units of one arm, each with its own true parameters and tracker data.

Used by the tests, benchmarks/fleet.py and examples/fleet. Each unit is `robocal simulate` of one
template config with the unit's own seed (seed per unit, so any subset is reproducible on its own).
The template is the UR5 demo with the parameters the tracker cannot determine fixed, so every
perturbed parameter is estimable and each unit's truth can be checked parameter by parameter.
Faults on purpose: `broken` units get a cell that is not a number, `shuffled` units get measurements
out of step with their joint readings (a logging fault: the fit converges to nonsense, 'diverged'),
`truth` sets chosen true parameter values of chosen units (e.g. one far from the fleet).
"""
from __future__ import annotations

import copy
import csv
import json
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

import numpy as np
import yaml

from robocal.workflows.simulate import simulate_dataset
from robocal.estimation.calibrate import calibrate
from robocal.workflows.setup import load_config

DEMO = files("robocal.io") / "demo" / "ur5_calibrate.yaml"


@dataclass
class SimulatedFleet:
    fleet_yaml: Path
    manifest: Path
    template: Path
    truth: dict[str, dict[str, float]]   # unit -> true parameter values


def unit_name(i: int) -> str:
    return f"U{i:03d}"


def fleet_template(folder: Path, samples: int) -> Path:
    """arm.yaml: the UR5 demo config with its unidentifiable parameters fixed and `samples` poses."""
    raw = yaml.safe_load(DEMO.read_text())
    demo = load_config(str(DEMO))
    unidentifiable = calibrate(demo.problem, demo.options).unidentifiable
    raw["parameters"]["fix"] = unidentifiable
    raw["data"]["csv"] = "data/unit.csv"
    raw["output"] = {"dir": "fleet-output", "report": False}   # report.html per unit: see docs/fleet.md
    raw["simulation"] = {"seed": 0, "samples": samples, "perturb": raw["simulation"]["perturb"]}
    path = folder / "arm.yaml"
    path.write_text("# UR5 tracker calibration used for every unit of the simulated fleet\n"
                    + yaml.safe_dump(raw, sort_keys=False))
    return path


def simulated_fleet(folder: str | Path, n_units: int, samples: int = 30, seed: int = 0, broken=(), shuffled=(),
                    truth: dict[int, dict[str, float]] | None = None, date: str = "2026-01-15",
                    max_sigma_ratio: float = 5.0) -> SimulatedFleet:
    """Write arm.yaml, data/U###.csv (+ _truth.json), units.csv and fleet.yaml into `folder`."""
    folder = Path(folder).resolve()
    (folder / "data").mkdir(parents=True, exist_ok=True)
    template = fleet_template(folder, samples)
    truths, rows = {}, []
    for i in range(n_units):
        name = unit_name(i)
        csv_path = folder / "data" / f"{name}.csv"
        config = template
        if truth and i in truth:   # a config of its own whose simulation sets these true values
            raw = yaml.safe_load(template.read_text())
            raw["simulation"]["truth"] = {k: float(v) for k, v in truth[i].items()}
            config = folder / "data" / f"{name}.yaml"
            config.write_text(yaml.safe_dump(raw, sort_keys=False))
        _, truth_path = simulate_dataset(config, csv_path, seed=seed * 100_003 + i, force=True)
        truths[name] = json.loads(truth_path.read_text())["parameters"]
        if i in shuffled:
            shuffle_measurements(csv_path, np.random.default_rng(i))
        if i in broken:
            break_cell(csv_path, row=7, column="x", text="0.1O3")
        rows.append({"unit": name, "data": f"data/{name}.csv", "serial": f"SN-{10000 + i}", "date": date,
                     "site": "line-A" if i % 2 == 0 else "line-B"})
    manifest = folder / "units.csv"
    with manifest.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    fleet_yaml = folder / "fleet.yaml"
    fleet_yaml.write_text(yaml.safe_dump({"config": "arm.yaml", "units": "units.csv",
                                          "output": {"dir": "fleet-output", "table": "fleet.parquet"},
                                          "accept": {"max_sigma_ratio": max_sigma_ratio}}, sort_keys=False))
    return SimulatedFleet(fleet_yaml, manifest, template, truths)


def shuffle_measurements(csv_path: Path, rng: np.random.Generator, first_measurement: str = "x") -> None:
    """Put the measurement cells (from column `first_measurement` on) of every row onto another row."""
    rows = list(csv.reader(csv_path.open(newline="")))
    header, body = rows[0], copy.deepcopy(rows[1:])
    j = header.index(first_measurement)
    perm = rng.permutation(len(body))
    out = [header] + [r[:j] + body[p][j:] for r, p in zip(rows[1:], perm)]
    with csv_path.open("w", newline="") as f:
        csv.writer(f).writerows(out)


def break_cell(csv_path: Path, row: int, column: str, text: str) -> None:
    """Replace one cell (data row `row`, 1-based after the header) with `text`."""
    rows = list(csv.reader(csv_path.open(newline="")))
    rows[row][rows[0].index(column)] = text
    with csv_path.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
