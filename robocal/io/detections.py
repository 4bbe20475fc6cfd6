"""The detections CSV of a camera: one row per corner seen, `sample, corner, u, v` (and an optional `sigma`).

`sample` names the sample (the image) by the label the joint-readings table gives it (its `sample` column, or
the 1-based row number when it has none); `corner` is a corner id of the target (robocal.io.camera_target); u, v
are pixels (OpenCV's convention: the centre of the top-left pixel is (0, 0)); `sigma` a per-corner pixel standard
deviation. Every error names the file, the line and the column (docs/camera.md).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robocal.errors import InputError
from robocal.io.tables import Table, read_csv
from robocal.io.text_files import write_atomic

COLUMNS = ("sample", "corner", "u", "v")


@dataclass
class Detections:
    """Corners seen in images: sample label, corner id, pixel, optional sigma, and the file line of each row."""

    source: str
    samples: np.ndarray             # (n,) sample labels (str)
    corners: np.ndarray             # (n,) int
    uv: np.ndarray                  # (n, 2) px
    sigma: np.ndarray | None = None  # (n,) px
    lines: np.ndarray | None = None  # (n,) file line of each row (None: made in memory)
    files: np.ndarray | None = None  # (n,) index into `sources` of each row's file, when read from several
    sources: tuple[str, ...] = ()

    def line(self, k: int) -> int | None:
        return None if self.lines is None else int(self.lines[k])

    def source_of(self, k: int) -> str:
        """The file row k was read from."""
        return self.source if self.files is None else self.sources[int(self.files[k])]

    def subset(self, keep: np.ndarray) -> "Detections":
        return Detections(self.source, self.samples[keep], self.corners[keep], self.uv[keep],
                          None if self.sigma is None else self.sigma[keep],
                          None if self.lines is None else self.lines[keep],
                          None if self.files is None else self.files[keep], self.sources)


def detections_from_table(tab: Table) -> Detections:
    missing = [c for c in COLUMNS if not tab.has(c)]
    if missing:
        raise InputError(f"a detections file needs the columns {', '.join(COLUMNS)} (missing: {', '.join(missing)}; "
                         f"present: {', '.join(tab.header)})", source=str(tab.path), field=missing[0])
    if not tab.n_rows:
        raise InputError("no detections in the file", source=str(tab.path))
    js = tab.header.index("sample")
    samples = np.array([row[js].strip() for row in tab.cells], dtype=object)
    for i, s in enumerate(samples):
        if not s:
            raise InputError("empty sample label", source=str(tab.path), row=tab.line(i), field="sample")
    corner = tab.column("corner")
    bad = np.flatnonzero(corner != np.round(corner))
    if len(bad):
        raise InputError(f"corner id {corner[bad[0]]:g} is not an integer", source=str(tab.path),
                         row=tab.line(int(bad[0])), field="corner")
    uv = np.column_stack([tab.column("u"), tab.column("v")])
    sigma = None
    if tab.has("sigma"):
        sigma = tab.column("sigma")
        bad = np.flatnonzero(sigma <= 0)
        if len(bad):
            raise InputError(f"a pixel sigma must be positive, got {sigma[bad[0]]:g}", source=str(tab.path),
                             row=tab.line(int(bad[0])), field="sigma")
    det = Detections(str(tab.path), samples, corner.astype(int), uv, sigma,
                     np.array([tab.line(i) for i in range(tab.n_rows)]))
    key = {}
    for k, (s, c) in enumerate(zip(det.samples, det.corners)):
        if (s, c) in key:
            raise InputError(f"sample {s} has corner {c} twice (first on line {det.line(key[(s, c)])})",
                             source=det.source, row=det.line(k), field="corner")
        key[(s, c)] = k
    return det


def read_detections(path: str | Path) -> Detections:
    """Read and check a detections CSV (columns in the module docstring)."""
    return detections_from_table(read_csv(path))


def read_detections_files(paths) -> Detections:
    """One file, or several read as one (a session's images each): every row keeps its file and line; a sample
    label in two files is refused (a detection names its image by label), and so is a sigma column in some files
    only."""
    parts = [read_detections(p) for p in paths]
    if len(parts) == 1:
        return parts[0]
    owner: dict[str, int] = {}
    for f, det in enumerate(parts):
        for k, s in enumerate(det.samples):
            if owner.setdefault(s, f) != f:
                raise InputError(f"sample {s} is also in {parts[owner[s]].source}: each image's label must be in one "
                                 "detections file", source=det.source, row=det.line(k), field="sample")
    with_sigma = [det.sigma is not None for det in parts]
    if any(with_sigma) and not all(with_sigma):
        f = with_sigma.index(False)
        raise InputError("a sigma column in some detections files only: give it in all or none",
                         source=parts[f].source, field="sigma")
    return Detections(", ".join(det.source for det in parts), np.concatenate([det.samples for det in parts]),
                      np.concatenate([det.corners for det in parts]), np.concatenate([det.uv for det in parts]),
                      np.concatenate([det.sigma for det in parts]) if all(with_sigma) else None,
                      np.concatenate([det.lines for det in parts]),
                      np.concatenate([np.full(len(det.samples), f) for f, det in enumerate(parts)]),
                      tuple(det.source for det in parts))


def detections_csv(det: Detections) -> str:
    """The CSV text of detections (what `write_detections` writes)."""
    lines = [",".join(COLUMNS + (("sigma",) if det.sigma is not None else ()))]
    for k in range(len(det.corners)):
        cells = [str(det.samples[k]), str(int(det.corners[k])), f"{det.uv[k, 0]:.6f}", f"{det.uv[k, 1]:.6f}"]
        if det.sigma is not None:
            cells.append(f"{det.sigma[k]:.6g}")
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def write_detections(path: str | Path, det: Detections) -> Path:
    """Write detections atomically (a failure leaves no half-written file)."""
    return write_atomic(path, detections_csv(det))
