"""Blending consecutive straight segments: a polyline with its corners rounded by circular arcs.

The patent's `params` can say that a motion blends into the next one (spec §3) but does not say
how. Here consecutive line segments through the given points are joined by an arc of `radius`
tangent to both, so the tangent u is continuous and the path never stops at a corner (the force
regulator keeps acting through it). The arc replaces the last d = r tan(theta/2) of one segment
and the first d of the next (theta the turn angle); both must fit inside their segments.
The path is parametrised by arc length, s = arc/total, so |f'| = total length everywhere and
f'' = total^2/r on the arcs (curvature jumps at the tangent points, allowed by Eqs. 5-6, which
only need f'' pointwise). The tool keeps one orientation.
"""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError
from robocal.dynamics.path import CartesianPath


class BlendedPath(CartesianPath):
    """points (k >= 2, 3) m, the polyline's vertices; radius m of every corner arc; rotation (3, 3)
    the tool orientation (identity if None)."""

    def __init__(self, points, radius: float, rotation=None):
        pts = np.asarray(points, float)
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 2 or not np.all(np.isfinite(pts)):
            raise InputError(f"blended path needs (k >= 2, 3) finite points, got {pts.shape}", field="points")
        if not radius > 0:
            raise InputError(f"blend radius must be > 0, got {radius}", field="radius")
        seg = np.diff(pts, axis=0)
        lengths = np.linalg.norm(seg, axis=1)
        if np.any(lengths < 1e-9):
            i = int(np.argmin(lengths))
            raise InputError(f"blended path: points {i} and {i + 1} coincide", row=i + 1, field="points")
        dirs = seg / lengths[:, None]
        self.pieces = []                      # ("line", start, direction, length) or ("arc", centre, e1, e2, r, angle)
        cursor = pts[0]
        for i in range(1, len(pts) - 1):
            a, b = dirs[i - 1], dirs[i]
            theta = float(np.arccos(np.clip(a @ b, -1.0, 1.0)))
            if theta < 1e-9:                  # collinear: no arc
                continue
            if theta > np.pi - 1e-6:
                raise InputError(f"blended path reverses at point {i}: no arc can join the segments",
                                 row=i, field="points")
            d = radius * np.tan(theta / 2)
            if d > 0.5 * lengths[i - 1] + 1e-12 or d > 0.5 * lengths[i] + 1e-12:
                raise InputError(f"blend radius {radius:g} m too large at point {i}: the arc needs {d:.4g} m of "
                                 f"each segment, which are {lengths[i - 1]:.4g} and {lengths[i]:.4g} m long",
                                 row=i, field="radius")
            enter = pts[i] - d * a
            self._line(cursor, enter)
            normal_in = b - (a @ b) * a
            normal_in /= np.linalg.norm(normal_in)
            centre = enter + radius * normal_in
            e1 = -normal_in                      # from the centre to the entry point
            self.pieces.append(("arc", centre, e1, a, radius, theta))
            cursor = pts[i] + d * b
        self._line(cursor, pts[-1])
        self.lengths = np.array([p[3] if p[0] == "line" else p[4] * p[5] for p in self.pieces])
        self.total = float(self.lengths.sum())
        self.breaks = np.r_[0.0, np.cumsum(self.lengths)] / self.total
        if rotation is not None:
            self.rotation0 = np.asarray(rotation, float)

    def _line(self, a: np.ndarray, b: np.ndarray) -> None:
        length = float(np.linalg.norm(b - a))
        if length > 1e-12:
            self.pieces.append(("line", a.copy(), (b - a) / length, length))

    @property
    def length(self) -> float:
        return self.total

    def derivatives(self, s):
        if not np.isfinite(s):
            raise InputError(f"path parameter must be finite, got {s}", field="s")
        i = int(np.clip(np.searchsorted(self.breaks, s, side="right") - 1, 0, len(self.pieces) - 1))
        arc = (float(s) - self.breaks[i]) * self.total          # arc length into piece i
        piece, L = self.pieces[i], self.total
        if piece[0] == "line":
            _, a, u, _ = piece
            return a + arc * u, L * u, np.zeros(3)
        _, c, e1, e2, r, _ = piece
        phi = arc / r
        radial = np.cos(phi) * e1 + np.sin(phi) * e2
        tangent = -np.sin(phi) * e1 + np.cos(phi) * e2
        return c + r * radial, L * tangent, -(L**2 / r) * radial
