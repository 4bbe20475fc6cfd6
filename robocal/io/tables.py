"""CSV tables of joint readings and measurements, checked cell by cell.

Every error names the file, the row (the line number in the file, header = line 1) and the column.
Units: lengths in the file may be metres, centimetres, millimetres or inches, angles radians or degrees
(declared in the config); values are converted to SI on reading, and metre columns holding
millimetre-sized values are refused rather than silently misread. A UTF-8 byte-order mark (spreadsheet
programs write one) is stripped, and the table keeps a note saying so.
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robocal.errors import InputError
from robocal.io.text_files import write_atomic

LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "in": 0.0254}
ANGLE_UNITS = {"rad": 1.0, "deg": np.pi / 180.0}
#: a metre column with values beyond this (m) almost certainly holds millimetres
MAX_PLAUSIBLE_METRES = 50.0
#: a radian column with values beyond this (rad) almost certainly holds degrees
MAX_PLAUSIBLE_RADIANS = 4 * np.pi
#: the UTF-8 byte-order mark: invisible, it would otherwise become part of the first column's name
BOM = "\ufeff"
#: characters that make two column names print alike: BOM, zero-width space, no-break space
INVISIBLE = "\ufeff\u200b\u00a0 "


@dataclass
class Table:
    path: Path
    header: list[str]
    cells: list[list[str]]
    notes: list[str] = field(default_factory=list)    # what reading changed in a usable file (a BOM stripped)

    @property
    def n_rows(self) -> int:
        return len(self.cells)

    def line(self, i: int) -> int:
        """File line number of data row i (0-based)."""
        return i + 2

    def has(self, name: str) -> bool:
        return name in self.header

    def column(self, name: str, kind: str = "", unit: str | None = None, rows: np.ndarray | None = None) -> np.ndarray:
        """Float column in SI units. kind: 'length', 'angle' or '' (dimensionless)."""
        if name not in self.header:
            lookalike = [h for h in self.header if h.strip(INVISIBLE) == name]
            hint = (f"; the column {lookalike[0]!r} looks the same but holds invisible characters: rename it"
                    if lookalike else "")
            raise InputError(f"missing column (columns present: {', '.join(self.header)}){hint}",
                             source=str(self.path), field=name)
        j = self.header.index(name)
        idx = range(self.n_rows) if rows is None else rows
        try:        # Python's float() on every cell, as the checks below: the same numbers, 3x faster
            out = np.fromiter((float(self.cells[i][j]) for i in idx), float, count=len(idx))
        except (ValueError, IndexError):
            out = None
        if out is None or not np.all(np.isfinite(out)):
            self.check_column(j, idx)
        return to_si(out, kind, unit, self, name, idx)

    def check_column(self, j: int, idx) -> None:
        """Raise for the first cell of column j (rows idx) that is not a finite number, naming its row."""
        name = self.header[j]
        for i in idx:
            text = self.cells[i][j].strip() if j < len(self.cells[i]) else ""
            try:
                v = float(text)
            except ValueError:
                raise InputError(f"'{text}' is not a number", source=str(self.path), row=self.line(i),
                                 field=name) from None
            if not np.isfinite(v):
                raise InputError(f"value is {text or 'empty'}", source=str(self.path), row=self.line(i), field=name)

    @classmethod
    def from_columns(cls, path: str | Path, columns: dict[str, np.ndarray]) -> "Table":
        """An in-memory table (nothing is written; `path` only names it in messages). Numbers are kept
        exactly: each cell is the shortest text that reads back as the same float."""
        names = list(columns)
        data = [np.asarray(columns[n], dtype=float).reshape(-1) for n in names]
        n = len(data[0]) if data else 0
        return cls(Path(path), names, [[repr(float(c[i])) for c in data] for i in range(n)])

    def rows_where(self, column: str, value) -> np.ndarray:
        if column not in self.header:
            raise InputError("missing column used in 'where'", source=str(self.path), field=column)
        j = self.header.index(column)
        return np.array([i for i, row in enumerate(self.cells) if row[j].strip() == str(value)], dtype=int)


# per quantity: its units, the SI one, the largest plausible SI magnitude, and what a larger one looks like
_QUANTITIES = {"length": (LENGTH_UNITS, "m", MAX_PLAUSIBLE_METRES, "metres", "millimetres", "mm"),
               "angle": (ANGLE_UNITS, "rad", MAX_PLAUSIBLE_RADIANS, "radians", "degrees", "deg")}


def to_si(values: np.ndarray, kind: str, unit: str | None, table: Table, name: str, idx) -> np.ndarray:
    if kind not in _QUANTITIES:
        return values
    units, si, largest, si_word, other_word, other = _QUANTITIES[kind]
    unit = unit or si
    if unit not in units:
        raise InputError(f"unknown {kind} unit '{unit}' ({', '.join(units)})", field=name)
    if unit == si and len(values) and np.max(np.abs(values)) > largest:
        k = int(np.argmax(np.abs(values)))
        raise InputError(f"value {values[k]:g} is not plausible in {si_word}; the column looks like {other_word} "
                         f"(declare the unit as {other})", source=str(table.path), row=table.line(list(idx)[k]),
                         field=name)
    return values * units[unit]


def read_csv(path: str | Path) -> Table:
    path = Path(path)
    if not path.is_file():
        raise InputError("data file not found", source=str(path))
    reader = None
    try:
        with path.open(newline="", encoding="utf-8") as f:
            bom = f.read(1) == BOM
            if not bom:
                f.seek(0)
            reader = csv.reader(f)
            rows = [r for r in reader if r and any(c.strip() for c in r)]
    except UnicodeDecodeError as exc:
        line = path.read_bytes()[:exc.start].count(b"\n") + 1
        raise InputError(f"not UTF-8 text (byte {exc.object[exc.start]:#x}); save the file as UTF-8 CSV",
                         source=str(path), row=line) from None
    except csv.Error as exc:   # a NUL byte, an unterminated quote at the end
        raise InputError(f"not a readable CSV file: {exc}", source=str(path),
                         row=reader.line_num if reader is not None else None) from None
    if not rows:
        raise InputError("the file is empty", source=str(path))
    header = [h.strip() for h in rows[0]]
    dup = {h for h in header if header.count(h) > 1}
    if dup:
        raise InputError(f"duplicate column names: {', '.join(sorted(dup))}", source=str(path), row=1)
    cells = rows[1:]
    for i, r in enumerate(cells):
        if len(r) != len(header):
            raise InputError(f"{len(r)} cells where the header has {len(header)}", source=str(path), row=i + 2)
    notes = [f"{path}: a UTF-8 byte-order mark (written by some spreadsheet programs) was stripped before the "
             f"header '{header[0]}'"] if bom else []
    return Table(path, header, cells, notes)


def write_csv(path: str | Path, columns: dict[str, np.ndarray], precision: int = 17) -> None:
    """Write columns atomically (robocal.io.text_files.write_atomic)."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    text = io.StringIO(newline="")
    w = csv.writer(text)
    w.writerow(names)
    for row in data:
        w.writerow([f"{v:.{precision}g}" for v in row])
    write_atomic(path, text.getvalue())
