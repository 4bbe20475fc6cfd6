"""Joint-state logs as three CSV files (positions, velocities, efforts) sharing a time column.

Each file has a time column (s) and one column per joint named by a pattern such as
`- {joint}_position` (the ROS joint_states export). The time stamps may be irregular but must be
strictly increasing and identical row by row across the three files: a mismatch is refused, naming
the file, row and field, rather than silently re-aligned. A log without a time column gives its sample
period instead (row k at k x period). A log faster than signal.max_rate_hz is reduced to it
(`reduce_joint_log`, rate_reduction.py). See docs/dynamics_tiago.md and docs/dynamics_motors.md.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
import re
import warnings
from pathlib import Path

import numpy as np

from robocal.dynamics.rate_reduction import RateReducer, describe, reduction_factor
from robocal.io.tables import BOM, read_csv
from robocal.errors import InputError

KINDS = ("position", "velocity", "effort")
DEFAULT_PATTERNS = {kind: f"- {{joint}}_{kind}" for kind in KINDS}
#: time stamps of two files that differ by more than this (s) are different samples
TIME_TOLERANCE = 1e-9
#: the largest relative departure of a time step from the log's median step when the log is reduced
STEP_TOLERANCE = 0.01


@dataclass
class JointLog:
    """t (T,) s, strictly increasing; q, v, effort (T, n) in the file's units, columns in `joints`
    order; files: {kind: path} the data came from (for error messages and provenance); unused_efforts:
    effort columns of the file for joints not asked for, holding non-zero values (ignored, noted)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    effort: np.ndarray
    joints: list[str]
    files: dict[str, str]
    unused_efforts: list[str] = field(default_factory=list)

    def window(self, start: float, stop: float) -> np.ndarray:
        """Boolean mask of the samples with start <= t < stop."""
        return (self.t >= start) & (self.t < stop)


def load_joint_log(files: dict[str, str | Path], joints: list[str], time_column: str = "t",
                   patterns: dict[str, str] | None = None, sample_period: float | None = None) -> JointLog:
    """Read the position, velocity and effort files (`files` keyed by KINDS) for `joints`.

    patterns: column name per kind with a `{joint}` placeholder (DEFAULT_PATTERNS otherwise); sample_period
    (s): the files have no time column, row k is at k x sample_period.
    Raises InputError naming the file, row and column for a missing column, a non-number, time
    stamps that do not increase, or time stamps that differ between the files.
    """
    patterns = {**DEFAULT_PATTERNS, **(patterns or {})}
    missing = [k for k in KINDS if k not in files]
    if missing:
        raise InputError(f"no file given for {', '.join(missing)}", source="config", field="data")
    tables = {kind: numeric_table(files[kind]) or read_csv(files[kind]) for kind in KINDS}
    if sample_period is not None:
        times = {kind: np.arange(tables[kind].n_rows) * float(sample_period) for kind in KINDS}
        time_column = "sample_period_s"
    else:
        times = {kind: tables[kind].column(time_column) for kind in KINDS}
    reference = "position"
    t = times[reference]
    _check_increasing(t, tables[reference], time_column)
    for kind in KINDS[1:]:
        other = times[kind]
        tab = tables[kind]
        if len(other) != len(t):
            raise InputError(f"{len(other)} rows where {tables[reference].path.name} has {len(t)}: the three "
                             "files must share their time stamps row by row", source=str(tab.path),
                             field=time_column)
        bad = np.flatnonzero(np.abs(other - t) > TIME_TOLERANCE)
        if bad.size:
            i = int(bad[0])
            raise InputError(f"time stamp {other[i]!r} differs from {t[i]!r} in {tables[reference].path.name} "
                             f"({bad.size} rows differ): the three files must share their time stamps",
                             source=str(tab.path), row=tab.line(i), field=time_column)
    columns = {}
    for kind in KINDS:
        tab = tables[kind]
        columns[kind] = np.column_stack([tab.column(patterns[kind].format(joint=j)) for j in joints]) \
            if joints else np.zeros((len(t), 0))
    return JointLog(t, columns["position"], columns["velocity"], columns["effort"], list(joints),
                    {k: str(tables[k].path) for k in KINDS}, _unused(tables["effort"], patterns["effort"], joints))


class NumericTable:
    """A CSV file whose every cell is a finite number, parsed by numpy's loadtxt (the same numbers as float() per
    cell, 5x faster than io.tables.Table's cell-by-cell path): what a Table gives for such a file."""

    def __init__(self, path: Path, header: list[str], values: np.ndarray):
        self.path, self.header, self.values = path, header, values
        self.n_rows = len(values)

    def line(self, i: int) -> int:
        return i + 2

    def column(self, name: str) -> np.ndarray:
        if name not in self.header:          # io.tables' error, with its hints
            return read_csv(self.path).column(name)
        return self.values[:, self.header.index(name)].copy()


def numeric_table(path: str | Path) -> NumericTable | None:
    """The file as a NumericTable, or None for anything else (a missing file, a byte-order mark, a cell that is no
    finite number, a row of another length, duplicate names): io.tables.read_csv then reads it and names the fault."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as f:
            first = f.readline()
            with warnings.catch_warnings():          # a file without rows: io.tables says so
                warnings.simplefilter("ignore", UserWarning)
                values = np.loadtxt(f, delimiter=",", ndmin=2, comments=None, quotechar='"')
    except (OSError, ValueError):        # UnicodeDecodeError is a ValueError
        return None
    header = [h.strip() for h in next(csv.reader([first]), [])]
    if (first.startswith(BOM) or not len(values) or values.shape[1] != len(header) or len(set(header)) != len(header)
            or not np.all(np.isfinite(values))):
        return None
    return NumericTable(path, header, values)


def _unused(table, pattern: str, joints: list[str]) -> list[str]:
    """Effort columns matching the pattern for other joints, with some non-zero value."""
    head, _, tail = pattern.partition("{joint}")
    matcher = re.compile(re.escape(head) + "(.+)" + re.escape(tail) + "$")
    out = []
    for name in table.header:
        m = matcher.match(name)
        if m and m.group(1) not in joints:
            try:
                values = table.column(name)
            except InputError:
                continue
            if np.any(values != 0):
                out.append(name)
    return out


def _check_increasing(t: np.ndarray, table, field: str) -> None:
    if len(t) < 3:
        raise InputError(f"only {len(t)} samples; a log needs at least 3", source=str(table.path), field=field)
    steps = np.diff(t)
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(f"time stamp {t[i]!r} does not increase (previous {t[i - 1]!r})", source=str(table.path),
                         row=table.line(i), field=field)


def reduce_joint_log(log: JointLog, max_rate_hz: float, block: int = 8192) -> tuple[JointLog, np.ndarray | None,
                                                                                   list[str]]:
    """(the log at most max_rate_hz, the raw efforts at its rows or None when not reduced, what was done). A
    reduced log needs a uniform rate: a step off the median by more than STEP_TOLERANCE is refused (row)."""
    steps = np.diff(log.t)
    period = float(np.median(steps))
    factor = reduction_factor(1.0 / period, max_rate_hz)
    if factor == 1:
        return log, None, []
    off = np.flatnonzero(np.abs(steps - period) > STEP_TOLERANCE * period)
    if off.size:
        raise InputError(f"time step {steps[off[0]] * 1e3:.4g} ms differs from the log's {period * 1e3:.4g} ms by more "
                         f"than {100 * STEP_TOLERANCE:g} %: reducing a kHz log needs a uniform rate (a dropped or "
                         "repeated sample?)", source=log.files["position"], row=int(off[0]) + 3, field="t")
    n = log.q.shape[1]
    values = np.column_stack([log.t, log.q, log.v, log.effort])
    reducer = RateReducer(factor, [0] + list(range(1 + 2 * n, values.shape[1])))
    for start in range(0, len(values), block):
        reducer.push(values[start:start + block])
    rows, out, raw = reducer.finish()
    if len(rows) < 3:
        raise InputError(f"{len(log.t)} rows leave {len(rows)} after the rate reduction's edges: too short",
                         source=log.files["position"], field="t")
    reduced = JointLog(raw[:, 0], out[:, 1:1 + n], out[:, 1 + n:1 + 2 * n], out[:, 1 + 2 * n:], log.joints, log.files,
                       log.unused_efforts)
    return reduced, raw[:, 1:], [describe(factor, 1.0 / period, len(log.t), len(rows), block)]
