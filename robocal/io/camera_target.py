"""A camera target's geometry: which corner ids it has and where they sit on it (docs/camera.md).

Layouts (lengths in `unit`, m by default), with OpenCV's corner numbering so that its detectors' ids carry over:
  checkerboard  {type: checkerboard, corners: [cols, rows], square: s}: inner corner id r*cols + c at (c s, r s, 0),
                the order cv2.findChessboardCorners returns
  charuco       {type: charuco, squares: [cols, rows], square: s, marker: m, dictionary: DICT_5X5_100}: chessboard
                corner id r*(cols-1) + c at ((c+1) s, (r+1) s, 0) (cv2.aruco.CharucoBoard)
  aruco_grid    {type: aruco_grid, markers: [cols, rows], marker: m, separation: g, dictionary: DICT_APRILTAG_36h11,
                first_id: 0}: corner id 4 * marker id + k (k = 0..3 clockwise from top-left, cv2.aruco.GridBoard);
                AprilTag grids are aruco grids with an AprilTag dictionary
  points        {type: points, points: {id: [x, y, z], ...}}: any target
The target frame: x along the rows of corners, y down the columns, z = x cross y, pointing away from the printed
face (a camera in front of the target looks along +z). Corners of the plane layouts have z = 0.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robocal.errors import InputError
from robocal.io.tables import LENGTH_UNITS

LAYOUTS = ("checkerboard", "charuco", "aruco_grid", "points")


@dataclass
class CameraTarget:
    """Corner ids and their positions (m) in the target frame, and the layout a detector needs."""

    kind: str
    ids: np.ndarray                 # (n,) int
    points: np.ndarray              # (n, 3) m
    layout: dict = field(default_factory=dict)   # sizes in m and counts, as given (for the image detectors)

    def __post_init__(self):
        self._row = {int(i): k for k, i in enumerate(self.ids)}

    @property
    def planar(self) -> bool:
        return bool(np.all(np.abs(self.points[:, 2]) < 1e-12))

    @property
    def size(self) -> float:
        """Largest distance between two corners (m)."""
        c = self.points - self.points.mean(axis=0)
        return float(2 * np.max(np.linalg.norm(c, axis=1))) if len(c) else 0.0

    def has(self, corner_id: int) -> bool:
        return int(corner_id) in self._row

    def points_of(self, corner_ids) -> np.ndarray:
        """(n, 3) positions of the given ids (KeyError for an unknown id: check with `has` first)."""
        return self.points[[self._row[int(i)] for i in np.asarray(corner_ids).reshape(-1)]]


def _pair(d: dict, key: str, source: str, prefix: str) -> tuple[int, int]:
    v = d.get(key)
    if (not isinstance(v, (list, tuple)) or len(v) != 2 or not all(isinstance(x, int) and not isinstance(x, bool)
                                                                   for x in v) or min(v) < 2):
        raise InputError(f"expected [cols, rows], two integers of at least 2, got {v!r}", source=source,
                         field=f"{prefix}.{key}")
    return int(v[0]), int(v[1])


def _length(d: dict, key: str, factor: float, source: str, prefix: str, default=None) -> float:
    v = d.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (np.isfinite(v) and v > 0):
        raise InputError(f"expected a positive length, got {v!r}", source=source, field=f"{prefix}.{key}")
    return float(v) * factor


def target_from_dict(d, source: str = "config", prefix: str = "target") -> CameraTarget:
    """The target of a config mapping (layouts in the module docstring); errors name the key."""
    if not isinstance(d, dict):
        raise InputError(f"expected a mapping with a 'type' ({', '.join(LAYOUTS)})", source=source, field=prefix)
    kind = d.get("type")
    if kind not in LAYOUTS:
        raise InputError(f"unknown target type {kind!r} (known: {', '.join(LAYOUTS)})", source=source,
                         field=f"{prefix}.type")
    unit = d.get("unit", "m")
    if unit not in LENGTH_UNITS:
        raise InputError(f"unknown length unit {unit!r} ({', '.join(LENGTH_UNITS)})", source=source,
                         field=f"{prefix}.unit")
    f = LENGTH_UNITS[unit]
    allowed = {"checkerboard": {"corners", "square"}, "charuco": {"squares", "square", "marker", "dictionary"},
               "aruco_grid": {"markers", "marker", "separation", "dictionary", "first_id"},
               "points": {"points"}}[kind] | {"type", "unit"}
    for k in d:
        if k not in allowed:
            raise InputError(f"unknown key for a {kind} target (allowed: {', '.join(sorted(allowed))})",
                             source=source, field=f"{prefix}.{k}")
    if kind == "checkerboard":
        cols, rows = _pair(d, "corners", source, prefix)
        s = _length(d, "square", f, source, prefix)
        c, r = np.meshgrid(np.arange(cols), np.arange(rows))
        pts = np.column_stack([c.ravel() * s, r.ravel() * s, np.zeros(cols * rows)])
        return CameraTarget(kind, np.arange(cols * rows), pts, {"corners": (cols, rows), "square": s})
    if kind == "charuco":
        cols, rows = _pair(d, "squares", source, prefix)
        s = _length(d, "square", f, source, prefix)
        m = _length(d, "marker", f, source, prefix)
        if m >= s:
            raise InputError(f"the marker ({m / f:g}) must be smaller than the square ({s / f:g})", source=source,
                             field=f"{prefix}.marker")
        c, r = np.meshgrid(np.arange(cols - 1), np.arange(rows - 1))
        pts = np.column_stack([(c.ravel() + 1) * s, (r.ravel() + 1) * s, np.zeros(c.size)])
        return CameraTarget(kind, np.arange(c.size), pts, {"squares": (cols, rows), "square": s, "marker": m,
                                                            "dictionary": str(d.get("dictionary", "DICT_5X5_100"))})
    if kind == "aruco_grid":
        cols, rows = _pair(d, "markers", source, prefix)
        m = _length(d, "marker", f, source, prefix)
        g = _length(d, "separation", f, source, prefix)
        first = d.get("first_id", 0)
        if isinstance(first, bool) or not isinstance(first, int) or first < 0:
            raise InputError(f"expected a marker id (integer >= 0), got {first!r}", source=source,
                             field=f"{prefix}.first_id")
        ids, pts = [], []
        for k in range(cols * rows):
            x0, y0 = (k % cols) * (m + g), (k // cols) * (m + g)
            for j, (dx, dy) in enumerate(((0, 0), (m, 0), (m, m), (0, m))):
                ids.append(4 * (first + k) + j)
                pts.append((x0 + dx, y0 + dy, 0.0))
        return CameraTarget(kind, np.array(ids), np.array(pts), {
            "markers": (cols, rows), "marker": m, "separation": g, "first_id": first,
            "dictionary": str(d.get("dictionary", "DICT_APRILTAG_36h11"))})
    raw = d.get("points")
    if not isinstance(raw, dict) or len(raw) < 4:
        raise InputError("expected a mapping of at least 4 corner ids to [x, y, z]", source=source,
                         field=f"{prefix}.points")
    ids, pts = [], []
    for key, xyz in raw.items():
        try:
            cid = int(key)
            p = np.asarray(xyz, dtype=float).reshape(3)
        except (TypeError, ValueError):
            raise InputError(f"expected an integer id and three numbers, got {key!r}: {xyz!r}", source=source,
                             field=f"{prefix}.points.{key}") from None
        if not np.all(np.isfinite(p)):
            raise InputError("coordinates must be finite", source=source, field=f"{prefix}.points.{key}")
        ids.append(cid)
        pts.append(p * f)
    if len(set(ids)) != len(ids):
        raise InputError("a corner id is given twice", source=source, field=f"{prefix}.points")
    return CameraTarget(kind, np.array(ids), np.array(pts), {})
