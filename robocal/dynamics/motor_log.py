"""Motor-side logs: motor encoder positions and motor efforts (currents or torques), one column per motor,
read block by block and brought to the working rate on the way (rate_reduction.py).

The position and effort columns may sit in one CSV file or two (then row by row with the same time stamps).
Columns are named by a pattern with `{motor}` (default `{motor}_position`, `{motor}_effort`). The columns
matching a kind's pattern must be the transmission's motors: a log with a column for a motor the
transmission does not have, or without one it has, is refused (its column count disagrees with the motors).
Time comes from a time column, or from `sample_period_s` when the log has none (row k at k x period).
Reduced logs need a uniform rate: a time step off the log's own by more than STEP_TOLERANCE (a dropped or
repeated sample) is refused, naming its row. Memory: one block of parsed rows (BLOCK rows x the columns read,
as text while parsing, ~60 B a cell) plus the reducer's reach, plus the reduced output: bounded whatever the
file's length. See docs/dynamics_motors.md.
"""
from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path

import numpy as np

from robocal.dynamics.log_loading import STEP_TOLERANCE, TIME_TOLERANCE
from robocal.dynamics.rate_reduction import RateReducer, describe, reduction_factor
from robocal.errors import InputError

KINDS = ("position", "effort")
DEFAULT_PATTERNS = {"position": "{motor}_position", "effort": "{motor}_effort"}
BLOCK = 8192


@dataclass
class MotorLog:
    """At the working rate: t (n,) s; position (n, nm) motor positions of `motors`; effort (n, ne) efforts of
    `logged`, anti-alias filtered; effort_raw (n, ne) the raw readings at those rows; lines (n,) the file
    line of each row; rate_hz: the file's rate; factor: the reduction; choices: what was done."""

    t: np.ndarray
    position: np.ndarray
    effort: np.ndarray
    effort_raw: np.ndarray
    lines: np.ndarray
    motors: list[str]
    logged: list[str]
    files: dict[str, str]
    rate_hz: float
    factor: int
    choices: list[str] = field(default_factory=list)


def column_names(header: list[str], pattern: str, motors: list[str], path: str, kind: str,
                 required: list[str]) -> dict[str, int]:
    """{motor: column index} for the columns matching `pattern`; refused when the file has one for a name not in
    `motors` or lacks one of `required`."""
    head, _, tail = pattern.partition("{motor}")
    if not _:
        raise InputError(f"the column pattern '{pattern}' has no {{motor}}", source="config", field=f"columns.{kind}")
    matcher = re.compile(re.escape(head) + "(.+)" + re.escape(tail) + "$")
    found = {m.group(1): i for i, name in enumerate(header) if (m := matcher.match(name.strip()))}
    extra = [n for n in found if n not in motors]
    missing = [m for m in required if m not in found]
    if extra or missing:
        raise InputError(f"{len(found)} {kind} columns ({', '.join(found) or 'none'}) where the transmission has "
                         f"{len(motors)} motors ({', '.join(motors)})"
                         + (f"; not a motor: {', '.join(extra)}" if extra else "")
                         + (f"; missing: {', '.join(pattern.format(motor=m) for m in missing)}" if missing else ""),
                         source=path, field=pattern)
    return {m: found[m] for m in required}


class _Reader:
    """One CSV file read in blocks of the named columns (float arrays), with file-line numbers."""

    def __init__(self, path: Path, columns: dict[str, int], time_column: str | None):
        self.path, self.handle = str(path), open(path, newline="", encoding="utf-8")
        self.rows = csv.reader(self.handle)
        self.header = next(self.rows, None)
        self.names = list(columns)
        self.index = list(columns.values())
        if time_column is not None:
            if time_column not in self.header:
                raise InputError(f"missing time column (columns present: {', '.join(self.header)}); a log without "
                                 "one needs sample_period_s", source=self.path, field=time_column)
            self.names.append(time_column)
            self.index.append(self.header.index(time_column))
        self.line = 2

    def block(self, size: int) -> np.ndarray:
        lines = list(islice(self.handle, size))     # the header was read through the csv reader: rows follow
        if not lines:
            return np.zeros((0, len(self.index)))
        try:        # numpy's C parser (float() on each cell, 5x faster); any doubt: the checked path below
            out = np.loadtxt(lines, delimiter=",", usecols=self.index, ndmin=2, comments=None, quotechar='"')
        except ValueError:
            out = None
        if out is not None and out.shape == (len(lines), len(self.index)) and np.all(np.isfinite(out)):
            self.line += len(lines)
            return out
        rows = list(csv.reader(lines))
        try:
            out = np.array([[r[i] for i in self.index] for r in rows], dtype=float).reshape(len(rows), len(self.index))
        except (ValueError, IndexError):
            out = None
        bad = None
        if out is not None:
            nonfinite = np.argwhere(~np.isfinite(out))
            bad = tuple(nonfinite[0]) if len(nonfinite) else None
        else:
            bad = next((k, c) for k, r in enumerate(rows) for c, i in enumerate(self.index) if not _number(r, i))
        if bad is not None:
            k, c = bad
            cell = rows[k][self.index[c]] if self.index[c] < len(rows[k]) else ""
            raise InputError(f"'{cell}' is not a finite number", source=self.path, row=self.line + int(k),
                             field=self.names[int(c)])
        self.line += len(rows)
        return out

    def close(self):
        self.handle.close()


def _number(row, i) -> bool:
    try:
        return i < len(row) and np.isfinite(float(row[i]))
    except ValueError:
        return False


def load_motor_log(files: dict[str, str | Path], motors: list[str], logged: list[str], time_column: str | None = "t",
                   sample_period: float | None = None, patterns: dict[str, str] | None = None,
                   max_rate_hz: float = 250.0, block: int = BLOCK) -> MotorLog:
    """Read `files` {position, effort} (one file may hold both) for the motors (positions of every motor,
    efforts of `logged`), reducing the rate to at most max_rate_hz on the way (module docstring)."""
    patterns = {**DEFAULT_PATTERNS, **(patterns or {})}
    paths = {k: Path(files[k]) for k in KINDS}
    for k, p in paths.items():
        if not p.is_file():
            raise InputError("log file not found", source=str(p), field=k)
    wanted: dict[Path, dict[str, int]] = {}
    for kind, names in (("position", motors), ("effort", logged)):
        header = _header(paths[kind])
        cols = column_names(header, patterns[kind], motors, str(paths[kind]), kind, names)
        wanted.setdefault(paths[kind], {}).update({f"{kind}:{m}": i for m, i in cols.items()})
    tc = None if sample_period is not None else time_column
    readers = [_Reader(p, cols, tc) for p, cols in wanted.items()]
    try:
        return _stream(readers, paths, motors, logged, tc, sample_period, max_rate_hz, block)
    finally:
        for r in readers:
            r.close()


def _header(path: Path) -> list[str]:
    with open(path, newline="", encoding="utf-8") as handle:
        header = next(csv.reader(handle), None)
    if not header:
        raise InputError("empty file", source=str(path), field="header")
    if all(_number([h], 0) for h in header):
        raise InputError("the first row holds numbers: the file needs a header row naming its columns",
                         source=str(path), row=1, field="header")
    return [h.strip() for h in header]


def _stream(readers, paths, motors, logged, time_column, sample_period, max_rate_hz, block) -> MotorLog:
    n_read, period, reducer, last_t = 0, sample_period, None, None
    while True:
        blocks = [r.block(block) for r in readers]
        sizes = {len(b) for b in blocks}
        if len(sizes) > 1:
            short = readers[int(np.argmin([len(b) for b in blocks]))]
            raise InputError(f"the file ends at line {short.line - 1} where the log's other file goes on: position "
                             "and effort files must share their rows", source=short.path, row=short.line)
        size = sizes.pop()
        if size == 0:
            break
        named = {n: b[:, i] for r, b in zip(readers, blocks) for i, n in enumerate(r.names)}
        if time_column is None:
            t = (n_read + np.arange(size)) * sample_period
        else:
            t = named[time_column] if len(readers) == 1 else _same_times(readers, blocks, time_column)
            period = _check_steps(t, last_t, period, readers[0], n_read, time_column, max_rate_hz)
            last_t = t[-1]
        if reducer is None:                       # the time stamps and the efforts' raw readings kept at the rows
            reducer = RateReducer(reduction_factor(1.0 / period, max_rate_hz),
                                  [0] + list(range(1 + len(motors), 1 + len(motors) + len(logged))))
        reducer.push(np.column_stack([t] + [named[f"position:{m}"] for m in motors]
                                     + [named[f"effort:{m}"] for m in logged]))
        n_read += size
    if reducer is None:
        raise InputError("no data rows", source=readers[0].path)
    rows, values, raw = reducer.finish()
    if len(rows) < 3:
        raise InputError(f"{n_read} rows leave {len(rows)} after the rate reduction's edges: too short",
                         source=readers[0].path)
    nm = len(motors)
    choices = [describe(reducer.factor, 1.0 / period, n_read, len(rows), block)]
    return MotorLog(raw[:, 0], values[:, 1:1 + nm], values[:, 1 + nm:], raw[:, 1:], rows + 2, list(motors),
                    list(logged), {k: str(p) for k, p in paths.items()}, 1.0 / period, reducer.factor, choices)


def _same_times(readers, blocks, time_column) -> np.ndarray:
    ref = blocks[0][:, readers[0].names.index(time_column)]
    for r, b in zip(readers[1:], blocks[1:]):
        other = b[:, r.names.index(time_column)]
        bad = np.flatnonzero(np.abs(other - ref) > TIME_TOLERANCE)
        if bad.size:
            i = int(bad[0])
            raise InputError(f"time stamp {other[i]!r} differs from {ref[i]!r} in {Path(readers[0].path).name}: the "
                             "position and effort files must share their time stamps", source=r.path,
                             row=r.line - len(b) + i, field=time_column)
    return ref


def _check_steps(t, last_t, period, reader, n_read, time_column, max_rate_hz) -> float:
    """Strictly increasing; the log's step (the first block's median) returned; with a reduction ahead, every step
    within STEP_TOLERANCE of it."""
    steps = np.diff(t if last_t is None else np.r_[last_t, t])
    first = 1 if last_t is None else 0                     # index in t of steps[0]'s later row
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        i = int(bad[0]) + first
        raise InputError(f"time stamp {t[i]!r} does not increase", source=reader.path,
                         row=reader.line - len(t) + i, field=time_column)
    if period is None:
        period = float(np.median(steps))
    if reduction_factor(1.0 / period, max_rate_hz) > 1:
        off = np.flatnonzero(np.abs(steps - period) > STEP_TOLERANCE * period)
        if off.size:
            i = int(off[0]) + first
            raise InputError(f"time step {steps[off[0]] * 1e3:.4g} ms differs from the log's {period * 1e3:.4g} ms by "
                             f"more than {100 * STEP_TOLERANCE:g} %: reducing a kHz log needs a uniform rate (a dropped "
                             "or repeated sample?)", source=reader.path, row=reader.line - len(t) + i,
                             field=time_column)
    return period
