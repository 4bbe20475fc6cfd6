"""The five measuring modes of Stewart platform calibration (docs/stewart_calibration.md) as robocal residuals.

Each mode reuses a core residual on the platform frame, with the tool tip tau = (0, 0, -L) carried
explicitly as the residual's (known) tip point and the probe's tip-ball radius r as its tip radius:

  mode 1  full pose (X, Y, Z, A, B, C) with per-axis weights u  -> PoseResidual (+ ToolAxisResidual)
  mode 2  reference plane (contact point, outward normal)        -> PlaneResidual
  mode 3  reference cylinder, hole (R - r) or pin (R + r)        -> CylinderResidual
  mode 4  reference ball (R + r)                                 -> SphereResidual
  mode 5  double ball bar, unknown origin offset `off`           -> BallBarResidual (one `off` per instrument)

Orientation: measured rows are (X, Y, Z, A, B, C) in metres and radians; `rotation`/`angles` convert
angles under a named convention: "xyz_intrinsic" R = Rx(A) Ry(B) Rz(C) (spec default), "zyx_rpy"
R = Rz(C) Ry(B) Rx(A) (Pinocchio's rpy). The pose residual compares rotations convention-free
(log3); its weights u_A, u_B, u_C weigh the rotation error about the measurement frame's X, Y, Z axes
(= the A, B, C angle errors to first order near A = B = C = 0). Rows that measure the tilt but not C
(u_C = 0, u_A = u_B > 0) become a tool-axis residual R e_z - R_meas e_z instead, which is exactly
"tilt only" whatever the convention: the spin about the tool axis is then unobserved.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.residuals import BallBarResidual, CylinderResidual, PlaneResidual, PoseResidual, SphereResidual
from robocal.residuals.tool_axis import ToolAxisResidual
from robocal.residuals.base import Residual

CONVENTIONS = ("xyz_intrinsic", "zyx_rpy")
PLATFORM = "platform"


def _check_convention(convention: str) -> None:
    if convention not in CONVENTIONS:
        raise InputError(f"unknown orientation convention '{convention}' (known: {', '.join(CONVENTIONS)})",
                         field="convention")


def rotation(abc, convention: str = "xyz_intrinsic") -> np.ndarray:
    """3x3 rotation of angles (A, B, C) in rad."""
    _check_convention(convention)
    a, b, c = np.asarray(abc, dtype=float).reshape(3)
    if convention == "zyx_rpy":
        return pin.rpy.rpyToMatrix(a, b, c)
    return pin.utils.rotate("x", a) @ pin.utils.rotate("y", b) @ pin.utils.rotate("z", c)


def angles(R: np.ndarray, convention: str = "xyz_intrinsic") -> np.ndarray:
    """(A, B, C) in rad of a rotation; B in [-pi/2, pi/2] (the inverse of `rotation` there)."""
    _check_convention(convention)
    R = np.asarray(R, dtype=float)
    if convention == "zyx_rpy":
        return pin.rpy.matrixToRpy(R)
    # R = Rx(A) Ry(B) Rz(C): R[0, 2] = sin B, R[1, 2] = -sin A cos B, R[2, 2] = cos A cos B,
    # R[0, 0] = cos B cos C, R[0, 1] = -cos B sin C
    b = np.arcsin(np.clip(R[0, 2], -1.0, 1.0))
    return np.array([np.arctan2(-R[1, 2], R[2, 2]), b, np.arctan2(-R[0, 1], R[0, 0])])


def numeric_rows(rows, width: int, source: str) -> np.ndarray:
    """(K, width) float rows; InputError naming the row and field of a bad cell."""
    try:
        m = np.asarray(rows, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"rows are not numeric: {exc}", source=source) from None
    m = m.reshape(1, -1) if m.ndim == 1 else m
    if m.ndim != 2 or m.shape[1] != width:
        raise InputError(f"expected rows of {width} values, got shape {np.shape(rows)}", source=source)
    bad = np.argwhere(~np.isfinite(m))
    if len(bad):
        r, c = bad[0]
        raise InputError("value is not finite", source=source, row=int(r) + 1, field=f"column {int(c) + 1}")
    return m


def pose_rows_to_xyzquat(rows, convention: str = "xyz_intrinsic", source: str = "pose rows") -> np.ndarray:
    """(K, 6) X Y Z A B C (m, rad) -> (K, 7) x y z qx qy qz qw: the PoseResidual's columns."""
    m = numeric_rows(rows, 6, source)
    return np.array([np.concatenate([r[:3], pin.Quaternion(rotation(r[3:], convention)).coeffs()]) for r in m])


def xyzquat_to_pose_rows(m, convention: str = "xyz_intrinsic", source: str = "pose rows") -> np.ndarray:
    """(K, 7) x y z qx qy qz qw -> (K, 6) X Y Z A B C (m, rad)."""
    m = numeric_rows(m, 7, source)
    out = []
    for r in m:
        qx, qy, qz, qw = r[3:] / np.linalg.norm(r[3:])
        out.append(np.concatenate([r[:3], angles(pin.Quaternion(qw, qx, qy, qz).toRotationMatrix(), convention)]))
    return np.array(out)


@dataclass(frozen=True)
class Tool:
    """Adjustment tool or probe on the platform: length L (tip at (0, 0, -L) in the platform frame, m)
    and tip-ball radius r (m; 0 for a point tool or a ball-bar ball centre)."""

    length: float
    tip_radius: float = 0.0

    @property
    def tip(self) -> np.ndarray:
        return np.array([0.0, 0.0, -float(self.length)])


def tool_frame(robot, tool: Tool) -> str:
    """A frame at the tool tip: the robot's `tool` frame if it sits there, else a new `tool_tip` frame."""
    for name in ("tool", "tool_tip"):
        if robot.model.existFrame(name):
            fid = robot.frame_id(name)
            rel = robot.model.frames[robot.frame_id(PLATFORM)].placement.actInv(robot.model.frames[fid].placement)
            if np.allclose(rel.rotation, np.eye(3), atol=1e-12) and np.allclose(rel.translation, tool.tip, atol=1e-12):
                return name
    if robot.model.existFrame("tool_tip"):
        raise InputError(f"the robot's tool_tip frame is not at the tool length {tool.length} m", field="length")
    robot.add_frame("tool_tip", PLATFORM, pin.SE3(np.eye(3), tool.tip))
    return "tool_tip"


def pose_residuals(name: str, robot, samples, rows, weights, tool: Tool, sigma=(1e-5, 1e-5),
                   convention: str = "xyz_intrinsic", source: str = "pose rows") -> list[Residual]:
    """Mode 1: measured tool-tip poses (K, 6) X Y Z A B C with weights u (6,) or (K, 6).

    u = 0 drops an axis (not measured); rows sharing a weight vector form one block named
    `<name>` (or `<name>_<g>` for the g-th distinct weight vector, in order of first use). Rows with
    u_C = 0 and u_A = u_B > 0 are tilt-only and add a ToolAxisResidual `<name>[_g]_axis`.
    sigma = (position m, angle rad).
    """
    m = numeric_rows(rows, 6, source)
    samples = np.asarray(samples, dtype=int).reshape(-1)
    if len(samples) != len(m):
        raise InputError(f"{len(m)} rows but {len(samples)} samples", source=source, field="samples")
    u = np.broadcast_to(np.asarray(weights, dtype=float), m.shape)
    if np.any(u < 0) or not np.all(np.isfinite(u)):
        r = int(np.argwhere((u < 0) | ~np.isfinite(u))[0, 0])
        raise InputError("weights must be finite and >= 0", source=source, row=r + 1, field="u")
    groups = list(dict.fromkeys(map(tuple, u)))
    frame = tool_frame(robot, tool)
    out: list[Residual] = []
    for g, w in enumerate(groups):
        idx = np.flatnonzero((u == w).all(axis=1))
        label = name if len(groups) == 1 else f"{name}_{g}"
        w = np.array(w)
        tilt_only = w[5] == 0 and (w[3] > 0 or w[4] > 0)
        if tilt_only and w[3] != w[4]:
            raise InputError("tilt-only rows (u_C = 0) must weigh A and B equally", source=source,
                             row=int(idx[0]) + 1, field="u")
        pose_w = w.copy()
        if tilt_only:
            pose_w[3:] = 0.0
        q = pose_rows_to_xyzquat(m[idx], convention, source)
        if np.any(pose_w):
            out.append(PoseResidual(label, frame, samples[idx], q, sigma=sigma, weights=pose_w))
        if tilt_only:
            axes = np.array([rotation(r[3:], convention)[:, 2] for r in m[idx]])
            out.append(ToolAxisResidual(f"{label}_axis", frame, samples[idx], axes, sigma=sigma[-1],
                                        weights=w[3]))
    return out


def plane_residual(name, samples, point, normal, tool: Tool, sigma=1e-5) -> PlaneResidual:
    """Mode 2: tip ball touching a known plane through `point` with outward unit `normal` (m)."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    return PlaneResidual(name, PLATFORM, samples, n, float(n @ np.asarray(point, dtype=float)), plane_unknown=False,
                         point=tool.tip, tip_radius=tool.tip_radius, sigma=sigma)


def cylinder_residual(name, samples, centre, axis, radius, tool: Tool, kind: str = "hole",
                      sigma=1e-5) -> CylinderResidual:
    """Mode 3: tip ball touching a known hole (tip at R - r from the axis) or pin (R + r)."""
    if kind not in ("hole", "pin"):
        raise InputError(f"cylinder kind '{kind}' (hole or pin)", field="kind")
    return CylinderResidual(name, PLATFORM, samples, centre, axis, radius, inside=kind == "hole",
                            axis_unknown=False, point=tool.tip, tip_radius=tool.tip_radius, sigma=sigma)


def ball_residual(name, samples, centre, radius, tool: Tool, sigma=1e-5, centre_unknown=False) -> SphereResidual:
    """Mode 4: tip ball touching a reference ball of radius R at a known (or unknown) centre."""
    return SphereResidual(name, PLATFORM, samples, centre, radius, centre_unknown=centre_unknown,
                          point=tool.tip, tip_radius=tool.tip_radius, sigma=sigma)


class InstrumentBallBar(BallBarResidual):
    """A ball bar set up at one place, whose origin offset belongs to the instrument: every place the same
    bar is set up at shares the one unknown `<instrument>.offset` (the problem keeps one parameter per name)."""

    def __init__(self, name, instrument: str, *args, **kwargs):
        super().__init__(name, *args, **kwargs)
        self.instrument = instrument

    def aux_parameters(self):
        out = super().aux_parameters()
        for p in out:
            if p.name == f"{self.name}.offset":
                p.name, p.target = f"{self.instrument}.offset", self.instrument
        return out


def ball_bar_residual(name, samples, readings, centre, tool: Tool, sigma=1e-5, offset=0.0,
                      centre_unknown=False, instrument: str | None = None) -> BallBarResidual:
    """Mode 5: double ball bar between a known fixed-ball centre and the tool tip; the bar's origin
    offset `off` (true length = reading + off; `offset` is its start value) is an unknown solved with the
    rest: `<name>.offset`, or `<instrument>.offset` shared by every place the one bar is set up at."""
    args = (PLATFORM, samples, np.asarray(readings, dtype=float).reshape(-1, 1), centre)
    kwargs = dict(offset=offset, centre_unknown=centre_unknown, offset_unknown=True, point=tool.tip, sigma=sigma)
    if instrument is None:
        return BallBarResidual(name, *args, **kwargs)
    return InstrumentBallBar(name, instrument, *args, **kwargs)
