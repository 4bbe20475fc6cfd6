"""Drawing primitives of the visual check: colours, the residual colour scale, arrows, triads, segments."""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.residuals.base import basis_from_normal
from robocal.viz import three_objects as three

COLOURS = {"measured": 0x202020, "before": 0xff8c00, "after": 0x1f77b4, "robot": 0x8ca6c0,
           "current": 0xd000d0, "artefact": 0x6fa86f, "laser": 0xe02020, "steel": 0xa0a0a0}
# Residual colour scale (fraction of the largest residual -> RGB): green, yellow, red.
SCALE_STOPS = np.array([[0.0, 0.10, 0.60, 0.31], [0.5, 0.99, 0.88, 0.55], [1.0, 0.84, 0.19, 0.15]])
ARROW_FRACTION = 0.08      # the largest arrow is drawn this fraction of the scene's size


def se3_from_pose7(p7) -> pin.SE3:
    x, y, z, qx, qy, qz, qw = p7
    return pin.SE3(pin.Quaternion(qw, qx, qy, qz).toRotationMatrix(), np.array([x, y, z]))


def pose_matrices(p7: np.ndarray) -> np.ndarray:
    """(..., 4, 4) homogeneous matrices of (..., 7) poses x y z qx qy qz qw (unit quaternions, as the scene
    stores them): se3_from_pose7 for whole arrays at once."""
    x, y, z, w = (p7[..., k] for k in (3, 4, 5, 6))
    T = np.zeros(p7.shape[:-1] + (4, 4))
    T[..., 0, 0], T[..., 0, 1], T[..., 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    T[..., 1, 0], T[..., 1, 1], T[..., 1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    T[..., 2, 0], T[..., 2, 1], T[..., 2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
    T[..., :3, 3] = p7[..., :3]
    T[..., 3, 3] = 1.0
    return T


def colour_scale(values: np.ndarray, vmax: float) -> np.ndarray:
    """(n, 3) RGB in [0, 1] for |values| on the green-yellow-red scale from 0 to vmax."""
    f = np.clip(np.abs(np.asarray(values, float)) / vmax, 0.0, 1.0) if vmax > 0 else np.zeros(len(values))
    return np.column_stack([np.interp(f, SCALE_STOPS[:, 0], SCALE_STOPS[:, c]) for c in (1, 2, 3)])


def nice_factor(x: float) -> float:
    """The largest 1-2-5 x 10^k not above x (arrow magnification reads as a round number)."""
    if not np.isfinite(x) or x <= 0:
        return 1.0
    e = np.floor(np.log10(x))
    m = x / 10 ** e
    return float((5 if m >= 5 else 2 if m >= 2 else 1) * 10 ** e)


def arrows(start: np.ndarray, vec: np.ndarray, colours: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Line-segment vertices (3, 6n) and colours of arrows start -> start + vec (shaft and two barbs)."""
    pos, col = [], []
    for a, v, c in zip(start, vec, colours):
        length = np.linalg.norm(v)
        if length == 0:
            continue
        u = v / length
        side = np.cross(u, [0.0, 0.0, 1.0] if abs(u[2]) < 0.9 else [1.0, 0.0, 0.0])
        side /= np.linalg.norm(side)
        tip = a + v
        for b in (a, tip - 0.25 * length * u + 0.1 * length * side, tip - 0.25 * length * u - 0.1 * length * side):
            pos += [b, tip]
            col += [c, c]
    return np.array(pos, np.float32).reshape(-1, 3).T, np.array(col, np.float32).reshape(-1, 3).T


def points_object(points: np.ndarray, colour: int, size: float):
    return three.Points(three.PointsGeometry(points.T.astype(np.float32)), three.PointsMaterial(size=size, color=colour))


def segments_object(pos: np.ndarray, col: np.ndarray | None = None, colour: int = 0xffffff):
    return three.LineSegments(three.PointsGeometry(pos, col),
                           three.LineBasicMaterial(color=colour, vertexColors=col is not None))


def segment_transform(a: np.ndarray, b: np.ndarray, radius_scale: float = 1.0) -> np.ndarray:
    """4x4 taking meshcat's unit cylinder (axis y, centred) onto the segment a -> b."""
    d = b - a
    # basis_from_normal gives a rotation with z along d; Rx(90 deg) brings y onto z.
    R = basis_from_normal(d) @ pin.rpy.rpyToMatrix(np.pi / 2, 0, 0)
    T = np.eye(4)
    T[:3, :3] = R @ np.diag([radius_scale, np.linalg.norm(d), radius_scale])
    T[:3, 3] = (a + b) / 2
    return T




def triads(origins: np.ndarray, rotations: np.ndarray, length: float,
           colours: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Line-segment vertices (3, 6n) and colours of n triads; colours (3, 3): the x, y, z axes' RGB."""
    pos, col = [], []
    for o, R in zip(origins, rotations):
        for k in range(3):
            pos += [o, o + length * R[:, k]]
            col += [colours[k], colours[k]]
    return np.array(pos, np.float32).reshape(-1, 3).T, np.array(col, np.float32).reshape(-1, 3).T


def magnified_rotations(R_pred: np.ndarray, R_meas: np.ndarray, factor: float) -> np.ndarray:
    """Rotations exp(factor log(R_pred R_meas^T)) R_meas: the prediction with its rotation error magnified."""
    return np.array([pin.exp3(factor * pin.log3(Rp @ Rm.T)) @ Rm for Rp, Rm in zip(R_pred, R_meas)])


def quat_rotations(quats) -> np.ndarray:
    """(n, 3, 3) rotations of (n, 4) quaternions x y z w."""
    return np.array([pin.Quaternion(w, x, y, z).normalized().toRotationMatrix() for x, y, z, w in quats])
