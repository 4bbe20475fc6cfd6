"""Path shapes f(s), s in [0, 1] (spec §4 A-B, §11.2 item 7).

Every path gives the TCP position f (3,) m and its derivatives f' (m), f'' (m) in s, and the
TCP pose at s. Cartesian paths also give the world-frame angular rate of the tool in s.
Joint paths (MOVEJF) interpolate joints, q = q0 + s (q1 - q0), and get f from forward kinematics.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin
from scipy.interpolate import CubicSpline

from robocal.errors import InputError

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _check_s(s: float) -> float:
    if not np.isfinite(s):
        raise InputError(f"path parameter must be finite, got {s}", field="s")
    return float(s)


class CartesianPath:
    """Base of paths defined in Cartesian space. Subclasses give `derivatives(s)` and may override
    `rotation(s)`; the tool keeps `rotation0` by default."""

    rotation0: np.ndarray = np.eye(3)

    def derivatives(self, s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(f, f', f'') at s, each (3,) m."""
        raise NotImplementedError

    def rotation(self, s: float) -> np.ndarray:
        return self.rotation0

    def angular_derivatives(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """(w', w'') (3,) rad: world-frame angular rate of the tool per unit s and its derivative
        (zero for a constant orientation)."""
        return np.zeros(3), np.zeros(3)

    def pose(self, s: float) -> pin.SE3:
        return pin.SE3(self.rotation(s), self.derivatives(s)[0])

    def check_regular(self, samples: int = 64) -> None:
        """Reject paths whose tangent vanishes (pure reorientation or a repeated point)."""
        for s in np.linspace(0.0, 1.0, samples):
            if np.linalg.norm(self.derivatives(s)[1]) < 1e-9:
                raise InputError(f"degenerate path: zero tangent at s = {s:.3f} (start equals target, "
                                 "or a pure reorientation)", field="position")


class LinearPath(CartesianPath):
    """MOVELF: straight line between two poses; position linear, orientation geodesic (spec §13.7)."""

    def __init__(self, start: pin.SE3, end: pin.SE3):
        self.start, self.end = start.copy(), end.copy()
        self.x0, self.dx = start.translation.copy(), end.translation - start.translation
        self._rot_log = pin.log3(start.rotation.T @ end.rotation)
        self.check_regular(2)

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.dx))

    def derivatives(self, s):
        s = _check_s(s)
        return self.x0 + s * self.dx, self.dx.copy(), np.zeros(3)

    def rotation(self, s):
        return self.start.rotation @ pin.exp3(s * self._rot_log)

    def angular_rate(self) -> np.ndarray:
        """World-frame d(orientation)/ds, rad (constant along a geodesic)."""
        return self.start.rotation @ self._rot_log

    def angular_derivatives(self, s):
        return self.angular_rate(), np.zeros(3)


class CircularPath(CartesianPath):
    """Arc or helix: centre (3,), radius m, unit normal, start direction (in the plane), sweep rad,
    pitch m per radian along the normal (0 for a circle). Tool orientation constant."""

    def __init__(self, centre, radius, normal, start_direction, sweep, pitch=0.0, rotation=None):
        n = np.asarray(normal, float) / np.linalg.norm(normal)
        e1 = np.asarray(start_direction, float)
        e1 = e1 - n * (n @ e1)
        if radius <= 0 or np.linalg.norm(e1) < 1e-12 or sweep == 0:
            raise InputError("circle needs radius > 0, a start direction off the normal and a non-zero sweep",
                             field="radius")
        self.c, self.r, self.n, self.sweep, self.pitch = np.asarray(centre, float), float(radius), n, float(sweep), float(pitch)
        self.e1 = e1 / np.linalg.norm(e1)
        self.e2 = np.cross(n, self.e1)
        if rotation is not None:
            self.rotation0 = np.asarray(rotation, float)

    def derivatives(self, s):
        th = self.sweep * _check_s(s)
        cs, sn, w = np.cos(th), np.sin(th), self.sweep
        f = self.c + self.r * (cs * self.e1 + sn * self.e2) + self.pitch * th * self.n
        df = w * (self.r * (-sn * self.e1 + cs * self.e2) + self.pitch * self.n)
        ddf = -w**2 * self.r * (cs * self.e1 + sn * self.e2)
        return f, df, ddf


class SplinePath(CartesianPath):
    """C2 cubic spline through points (k, 3) at uniform s; f'' is continuous as Eq. 6 requires."""

    def __init__(self, points, rotation=None):
        pts = np.asarray(points, float)
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 2:
            raise InputError(f"spline needs (k >= 2, 3) points, got {pts.shape}", field="points")
        self._spline = CubicSpline(np.linspace(0, 1, len(pts)), pts, bc_type="natural")
        self._d1, self._d2 = self._spline.derivative(1), self._spline.derivative(2)
        if rotation is not None:
            self.rotation0 = np.asarray(rotation, float)
        self.check_regular()

    def derivatives(self, s):
        s = _check_s(s)
        return self._spline(s), self._d1(s), self._d2(s)


class JointPath:
    """MOVEJF: q(s) = q0 (+) s dq with dq = difference(q0, q1); f = k(q(s)) at frame `frame_id`.

    f' and f'' come from forward kinematics with velocity dq and zero acceleration (the classical
    acceleration, spec §11.1). Joint derivatives are h' = dq, h'' = 0.
    """

    def __init__(self, model: pin.Model, frame_id: int, q0: np.ndarray, q1: np.ndarray):
        self.model, self.data, self.frame_id = model, model.createData(), frame_id
        self.q0 = np.array(q0, float)
        self.q1 = np.array(q1, float)
        self.dq = pin.difference(model, self.q0, self.q1)
        if np.linalg.norm(self.dq) < 1e-12:
            raise InputError("degenerate joint path: start equals target", field="position")
        self._zero = np.zeros(model.nv)

    def q_of_s(self, s: float) -> np.ndarray:
        return pin.integrate(self.model, self.q0, _check_s(s) * self.dq)

    def derivatives(self, s):
        m, d, f = self.model, self.data, self.frame_id
        pin.forwardKinematics(m, d, self.q_of_s(s), self.dq, self._zero)
        pin.updateFramePlacement(m, d, f)
        vel = pin.getFrameVelocity(m, d, f, _LWA).linear
        acc = pin.getFrameClassicalAcceleration(m, d, f, _LWA).linear
        return d.oMf[f].translation.copy(), vel.copy(), acc.copy()

    def joint_derivatives(self, s):
        """(h, h', h'') in joint space: (q(s), dq, 0)."""
        return self.q_of_s(s), self.dq.copy(), self._zero.copy()

    def pose(self, s) -> pin.SE3:
        pin.framesForwardKinematics(self.model, self.data, self.q_of_s(s))
        return self.data.oMf[self.frame_id].copy()
