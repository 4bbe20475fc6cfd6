"""The fleet table: one Parquet row per unit (and date), rewritten atomically as units finish.

Fixed columns (IDENTITY + OUTCOME) come first; then the figures of the fits (rms_before:BLOCK:UNIT,
rms_after:BLOCK:UNIT) and every parameter's estimate and standard error (est:NAME, se:NAME), float64,
in the order they first appear. A file is never half written: the table goes to a temporary file
beside it that os.replace moves into place.
"""
from __future__ import annotations

from pathlib import Path

from robocal.errors import InputError
from robocal.io.text_files import write_atomic

IDENTITY = ("key", "unit", "date", "serial", "site", "input_hash", "config_hash")
OUTCOME = ("status", "message", "iterations", "rows", "sigma_ratio", "condition", "elapsed_s", "worker",
           "output_dir")
INTEGER = ("iterations", "rows")
FLOAT = ("sigma_ratio", "condition", "elapsed_s")


def schema_of(rows: list[dict]):
    """The pyarrow schema of these rows: fixed columns, then float64 figure and parameter columns."""
    import pyarrow as pa   # optional [fleet] extra

    fields = []
    for name in IDENTITY + OUTCOME:
        kind = pa.int64() if name in INTEGER else pa.float64() if name in FLOAT else pa.string()
        fields.append(pa.field(name, kind))
    fixed = set(IDENTITY + OUTCOME)
    extra = dict.fromkeys(k for r in rows for k in r if k not in fixed)
    fields += [pa.field(name, pa.float64()) for name in extra]
    return pa.schema(fields)


def write_table(path: str | Path, rows: list[dict]) -> Path:
    """Write `rows` as a Parquet file atomically (temporary file + os.replace)."""
    import pyarrow as pa   # optional [fleet] extra
    import pyarrow.parquet as pq

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    schema = schema_of(rows)
    table = pa.Table.from_pylist([{k: r.get(k) for k in schema.names} for r in rows], schema=schema)
    sink = pa.BufferOutputStream()      # the whole file in memory (a fleet table is small), then written atomically
    pq.write_table(table, sink)
    return write_atomic(path, sink.getvalue().to_pybytes())


def read_table(path: str | Path) -> list[dict]:
    """The rows of a fleet table (an InputError naming the file if it is not one)."""
    import pyarrow.lib   # optional [fleet] extra
    import pyarrow.parquet as pq

    path = Path(path)
    if not path.is_file():
        raise InputError("fleet table not found", source=str(path))
    try:
        table = pq.read_table(path)
    except pyarrow.lib.ArrowException as exc:
        raise InputError(f"not a Parquet file: {exc}", source=str(path)) from None
    missing = [c for c in IDENTITY + ("status",) if c not in table.column_names]
    if missing:
        raise InputError(f"not a fleet table: no column {', '.join(missing)}", source=str(path))
    return table.to_pylist()


class FleetTable:
    """The rows of a fleet table by key, kept in memory and written out after every change."""

    def __init__(self, path: str | Path, rows: list[dict] | None = None):
        self.path = Path(path)
        self.rows = {r["key"]: r for r in rows or []}

    @classmethod
    def open(cls, path: str | Path) -> "FleetTable":
        """The table at `path`, or an empty one if there is no file yet."""
        return cls(path, read_table(path) if Path(path).is_file() else [])

    def is_done(self, job, final_statuses) -> bool:
        """The unit's row exists for these inputs and this config, with a final status."""
        r = self.rows.get(job.key)
        return (r is not None and r.get("input_hash") == job.input_hash and r.get("config_hash") == job.config_hash
                and r.get("status") in final_statuses)

    def put(self, row: dict) -> None:
        self.rows[row["key"]] = row

    def write(self) -> Path:
        return write_table(self.path, sorted(self.rows.values(), key=lambda r: (r["unit"], r["date"] or "")))
