"""fleet.yaml and its units: which data each unit has, and the hashes that say whether it is done.

    config: arm.yaml                 # the calibration config every unit uses (docs/config.md)
    units: units.csv                 # a manifest CSV, or {glob: "data/*.csv"} (unit = file stem)
    output: {dir: fleet-output, table: fleet.parquet}   # unit folders go to <dir>/units/<key>/
    accept: {max_sigma_ratio: 5}     # a converged fit whose residual/sigma exceeds this is 'diverged'

Manifest columns: unit and data (required; paths relative to the manifest), and optionally urdf (a
unit's own URDF instead of the config's robot), serial, date (YYYY-MM-DD), site, and `data:<file>`
for a config whose measurement blocks read other CSVs (`csv: <file>`). A unit calibrated more than
once has one row per date. Units are identified by `key` = unit, or unit_date when a date is given.
See docs/fleet.md.
"""
from __future__ import annotations

import csv
import datetime
import glob
import hashlib
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

from robocal.errors import InputError
from robocal.io.yaml_files import read_yaml
from robocal.workflows.config_keys import Cfg
from robocal.workflows.config_read import read_config
from robocal.workflows.config_types import CalibrationConfig

FLEET_KEYS = ("config", "units", "output", "accept")
MANIFEST_COLUMNS = ("unit", "data", "urdf", "serial", "date", "site")
UNIT_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
DEFAULT_MAX_SIGMA_RATIO = 5.0


@dataclass(frozen=True)
class UnitJob:
    """Everything a worker needs to calibrate one unit (plain data: it is pickled to the worker)."""

    key: str
    unit: str
    date: str
    serial: str
    site: str
    data: dict              # template CSV name ('' = data.csv) -> this unit's file (absolute)
    urdf: str | None        # this unit's URDF (absolute) or None: the config's robot
    template: str           # the calibration config (absolute)
    config: CalibrationConfig   # its checked config
    output_dir: str
    input_hash: str
    config_hash: str
    max_sigma_ratio: float
    source: str             # manifest file and row, for messages

    def identity(self) -> dict:
        return {"key": self.key, "unit": self.unit, "date": self.date, "serial": self.serial, "site": self.site,
                "input_hash": self.input_hash, "config_hash": self.config_hash, "output_dir": self.output_dir}


@dataclass
class FleetSpec:
    path: Path
    template: Path
    output_dir: Path
    table_path: Path
    jobs: list[UnitJob] = field(default_factory=list)


def file_hash(path: str | Path) -> str:
    """sha256 of a file's bytes ('missing' for a file that does not exist: the unit's row says why)."""
    p = Path(path)
    if not p.is_file():
        return "missing"
    return hashlib.sha256(p.read_bytes()).hexdigest()


def combined_hash(parts: dict) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:32]


def load_fleet(path: str | Path) -> FleetSpec:
    """Parse fleet.yaml, its template config and its manifest; every unit becomes a UnitJob."""
    path = Path(path).resolve()
    root = Cfg(read_yaml(path), "", str(path))
    root.check_keys(FLEET_KEYS)
    template = (path.parent / root.get("config", required=True, types=str)).resolve()
    config = read_config(template)      # the whole template checked before any unit runs
    out = root.child("output", {})
    out.check_keys(("dir", "table"))
    output_dir = (path.parent / out.get("dir", "fleet-output", types=str)).resolve()
    table_path = (output_dir / out.get("table", "fleet.parquet", types=str)).resolve()
    accept = root.child("accept", {})
    accept.check_keys(("max_sigma_ratio",))
    max_ratio = float(accept.get("max_sigma_ratio", DEFAULT_MAX_SIGMA_RATIO, types=(int, float)))
    robot_urdf = config.robot.urdf
    config_hash = combined_hash({"config": config.to_dict(), "max_sigma_ratio": max_ratio,
                                 "urdf": file_hash(robot_urdf) if robot_urdf else None})
    units = root.get("units", required=True, types=(str, dict))
    rows = _glob_rows(root, path.parent, units) if isinstance(units, dict) else _manifest_rows(path.parent / units)
    jobs, seen = [], {}
    for source, r in rows:
        key = f"{r['unit']}_{r['date']}" if r["date"] else r["unit"]
        if key in seen:
            raise InputError(f"unit '{r['unit']}' with date '{r['date']}' is listed twice (first at {seen[key]})",
                             source=source)
        seen[key] = source
        files = {**r["data"], **({"urdf": r["urdf"]} if r["urdf"] else {})}
        input_hash = combined_hash({name: file_hash(p) for name, p in files.items()})
        jobs.append(UnitJob(key, r["unit"], r["date"], r["serial"], r["site"], r["data"], r["urdf"], str(template),
                            config, str(output_dir / "units" / key), input_hash, config_hash, max_ratio, source))
    if not jobs:
        raise root.error("no units: the manifest is empty or the glob matches no file", "units")
    return FleetSpec(path, template, output_dir, table_path, jobs)


def _manifest_rows(manifest: Path) -> list[tuple[str, dict]]:
    manifest = manifest.resolve()
    if not manifest.is_file():
        raise InputError("manifest not found", source=str(manifest))
    with manifest.open(newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        header = [h.strip() for h in reader.fieldnames or []]
        for needed in ("unit", "data"):
            if needed not in header:
                raise InputError(f"missing column (columns present: {', '.join(header)})", source=str(manifest),
                                 row=1, field=needed)
        out = []
        for line, cells in enumerate(reader, start=2):
            cells = {k.strip(): (v or "").strip() for k, v in cells.items() if k is not None}
            if not any(cells.values()):
                continue
            out.append((f"{manifest}, row {line}", _unit_row(cells, manifest, line)))
    return out


def _unit_row(cells: dict, manifest: Path, line: int) -> dict:
    def bad(msg, col):
        return InputError(msg, source=str(manifest), row=line, field=col)

    unit = cells.get("unit", "")
    if not UNIT_NAME.match(unit):
        raise bad(f"'{unit}' is not a unit name (letters, digits, '_', '.', '-'; not empty)", "unit")
    date = cells.get("date", "")
    if date:
        try:
            datetime.date.fromisoformat(date)
        except ValueError:
            raise bad(f"'{date}' is not a date (YYYY-MM-DD)", "date") from None
    if not cells.get("data"):
        raise bad("no data file", "data")
    base = manifest.parent
    data = {"": str((base / cells["data"]).resolve())}
    for col, v in cells.items():
        if col.startswith("data:") and v:
            data[col[len("data:"):]] = str((base / v).resolve())
    urdf = str((base / cells["urdf"]).resolve()) if cells.get("urdf") else None
    return {"unit": unit, "date": date, "serial": cells.get("serial", ""), "site": cells.get("site", ""),
            "data": data, "urdf": urdf}


def _glob_rows(root: Cfg, base: Path, units: dict) -> list[tuple[str, dict]]:
    spec = root.child("units")
    spec.check_keys(("glob",))
    pattern = spec.get("glob", required=True, types=str)
    out = []
    for p in sorted(glob.glob(str(base / pattern))):
        unit = Path(p).stem
        if not UNIT_NAME.match(unit):
            raise spec.error(f"file '{p}' does not give a unit name (letters, digits, '_', '.', '-')", "glob")
        out.append((p, {"unit": unit, "date": "", "serial": "", "site": "", "data": {"": str(Path(p).resolve())},
                        "urdf": None}))
    return out
