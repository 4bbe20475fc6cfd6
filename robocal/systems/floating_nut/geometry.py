"""Geometry of the rod-end-floating hexapod (Stewart platform whose ball-screw nuts roll freely).

Each strut i joins a base Hooke joint centred at b_i to a platform Hooke joint centred at m_i.
The nut is free to roll about the strut, so a platform motion that rolls the rod also screws
the nut along the screw: the true strut length differs from the motor-encoder length by
l_a = sigma * lead * theta / (2 pi). See docs/floating_nut_hexapod.md.

Poses are p = [x, y, z, alpha, beta, gamma] (m, rad); the rotation convention is configurable:
  "ZYX-fixed"  R = Rz(gamma) Ry(beta) Rx(alpha)   (default; fixed-axis roll-pitch-yaw)
  "XYZ-moving" R = Rx(alpha) Ry(beta) Rz(gamma)
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from robocal.errors import InputError

N_LEGS = 6
EULER_CONVENTIONS = ("ZYX-fixed", "XYZ-moving")
_SOURCE = "FloatingNutGeometry"


# ---- rotation conventions (vectorised over poses) ----------------------------------------
def rotation_matrices(angles: np.ndarray, euler: str = "ZYX-fixed") -> np.ndarray:
    """Rotation matrices of platform orientations.

    angles: (..., 3) [alpha, beta, gamma] in rad. Returns (..., 3, 3).
    """
    a = np.asarray(angles, dtype=float)
    c, s = np.cos(a), np.sin(a)          # two calls for all angles: this runs inside Newton loops
    ca, cb, cg = c[..., 0], c[..., 1], c[..., 2]
    sa, sb, sg = s[..., 0], s[..., 1], s[..., 2]
    if euler == "ZYX-fixed":     # Rz(g) Ry(b) Rx(a)
        entries = [cg * cb, cg * sb * sa - sg * ca, cg * sb * ca + sg * sa,
                   sg * cb, sg * sb * sa + cg * ca, sg * sb * ca - cg * sa,
                   -sb, cb * sa, cb * ca]
    elif euler == "XYZ-moving":  # Rx(a) Ry(b) Rz(g)
        entries = [cb * cg, -cb * sg, sb,
                   ca * sg + sa * sb * cg, ca * cg - sa * sb * sg, -sa * cb,
                   sa * sg - ca * sb * cg, sa * cg + ca * sb * sg, ca * cb]
    else:
        raise InputError(f"unknown rotation convention '{euler}'; known: {', '.join(EULER_CONVENTIONS)}",
                         source=_SOURCE, field="euler")
    return np.stack(entries, axis=-1).reshape(ca.shape + (3, 3))


def omega_maps(angles: np.ndarray, euler: str = "ZYX-fixed") -> np.ndarray:
    """Maps T from Euler-angle rates to the angular velocity in the base frame: omega = T @ rates.

    angles: (..., 3) in rad. Returns (..., 3, 3) whose columns are the three rotation axes in
    the base frame.
    """
    a = np.asarray(angles, dtype=float)
    al, be, ga = a[..., 0], a[..., 1], a[..., 2]
    o, z = np.ones_like(al), np.zeros_like(al)
    if euler == "ZYX-fixed":   # omega = Rz Ry e_x da + Rz e_y db + e_z dg
        cb, sb, cg, sg = np.cos(be), np.sin(be), np.cos(ga), np.sin(ga)
        rows = [cg * cb, -sg, z, sg * cb, cg, z, -sb, z, o]
    elif euler == "XYZ-moving":  # omega = e_x da + Rx e_y db + Rx Ry e_z dg
        ca, sa, cb, sb = np.cos(al), np.sin(al), np.cos(be), np.sin(be)
        rows = [o, z, sb, z, ca, -sa * cb, z, sa, ca * cb]
    else:
        raise InputError(f"unknown rotation convention '{euler}'; known: {', '.join(EULER_CONVENTIONS)}",
                         source=_SOURCE, field="euler")
    return np.stack(rows, axis=-1).reshape(al.shape + (3, 3))


def angles_from_rotation(R: np.ndarray, euler: str = "ZYX-fixed") -> np.ndarray:
    """Inverse of `rotation_matrices` for one matrix (3, 3): [alpha, beta, gamma] in rad (|beta| < pi/2)."""
    R = np.asarray(R, dtype=float)
    if euler == "ZYX-fixed":     # R = Rz(g) Ry(b) Rx(a)
        return np.array([np.arctan2(R[2, 1], R[2, 2]), np.arcsin(np.clip(-R[2, 0], -1, 1)),
                         np.arctan2(R[1, 0], R[0, 0])])
    if euler == "XYZ-moving":    # R = Rx(a) Ry(b) Rz(g)
        return np.array([np.arctan2(-R[1, 2], R[2, 2]), np.arcsin(np.clip(R[0, 2], -1, 1)),
                         np.arctan2(-R[0, 1], R[0, 0])])
    raise InputError(f"unknown rotation convention '{euler}'; known: {', '.join(EULER_CONVENTIONS)}",
                     source=_SOURCE, field="euler")


# ---- thread conventions -------------------------------------------------------------------
def sigma_from_thread(hand: str, nut_side: str = "platform") -> int:
    """Sign of the additional length l_a = sigma * lead * theta / (2 pi).

    theta is the roll of the nut-side body relative to the screw side, positive about the strut
    axis pointing from base to platform. A right-hand thread with the nut on the platform side
    gives sigma = -1; a left-hand thread flips it, and so does a nut on the base side.
    """
    if hand not in ("right", "left"):
        raise InputError(f"thread hand must be 'right' or 'left', got '{hand}'", source=_SOURCE,
                         field="hand")
    if nut_side not in ("platform", "base"):
        raise InputError(f"nut side must be 'platform' or 'base', got '{nut_side}'", source=_SOURCE,
                         field="nut_side")
    sigma = -1 if hand == "right" else 1
    return sigma if nut_side == "platform" else -sigma


def thread_hand(sigma: int, nut_side: str = "platform") -> str:
    """Inverse of `sigma_from_thread`."""
    right = sigma_from_thread("right", nut_side)
    return "right" if int(sigma) == right else "left"


# ---- the geometry ------------------------------------------------------------------------
def _legs_array(value, shape, name, dtype=float) -> np.ndarray:
    try:
        arr = np.array(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise InputError(f"cannot read '{name}' as numbers: {exc}", source=_SOURCE, field=name) from exc
    if arr.shape != shape and arr.ndim == 0 and len(shape) == 1:
        arr = np.full(shape, arr, dtype=dtype)
    if arr.shape != shape:
        raise InputError(f"'{name}' must have shape {shape}, got {arr.shape}", source=_SOURCE, field=name)
    if not np.all(np.isfinite(arr)):
        raise InputError(f"'{name}' has non-finite entries", source=_SOURCE, field=name)
    arr.flags.writeable = False
    return arr


def _unit_rows(vectors: np.ndarray, name: str) -> np.ndarray:
    norms = np.linalg.norm(vectors, axis=1)
    bad = np.flatnonzero(norms < 1e-12)
    if bad.size:
        raise InputError(f"'{name}' of leg {bad[0] + 1} is a zero vector; a Hooke axis needs a direction",
                         source=_SOURCE, field=name)
    out = vectors / norms[:, None]
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class FloatingNutGeometry:
    """Everything the closed-form kinematics need; immutable (use `with_changes` for variants).

    b          (6, 3) base Hooke centres in the base frame {O_b}, m
    m          (6, 3) platform Hooke centres in the platform frame {O_m}, m
    p0         (6,)   home pose [x y z alpha beta gamma] (m, rad): the pose where every nut
                      rotation theta is zero and the encoders are referenced
    lead       (6,)   screw lead L = starts * pitch, m per revolution (0 disables compensation)
    sigma      (6,)   +1 / -1, sign of l_a (see `sigma_from_thread`)
    base_axes  (6, 3) base-fixed Hooke axes a_i in {O_b} (unit; default b_i/|b_i|, the patent)
    plat_axes  (6, 3) platform-fixed Hooke axes c_i in {O_m} (unit; default m_i/|m_i|)
    starts     (6,)   number of thread starts (documentation and URDF only; pitch = lead/starts)
    nut_side   "platform" or "base": where the nut sits (only used to name the thread hand)
    gear_ratio (6,)   motor revolutions per screw revolution
    euler      rotation convention, one of EULER_CONVENTIONS
    """

    b: np.ndarray
    m: np.ndarray
    p0: np.ndarray
    lead: np.ndarray = 0.01
    sigma: np.ndarray = 1
    base_axes: np.ndarray | None = None
    plat_axes: np.ndarray | None = None
    starts: np.ndarray = 1
    nut_side: str = "platform"
    gear_ratio: np.ndarray = 1.0
    euler: str = "ZYX-fixed"
    name: str = field(default="floating_nut_hexapod", compare=False)

    def __post_init__(self):
        put = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 - frozen dataclass init
        put("b", _legs_array(self.b, (N_LEGS, 3), "b"))
        put("m", _legs_array(self.m, (N_LEGS, 3), "m"))
        put("p0", _legs_array(self.p0, (6,), "p0"))
        put("lead", _legs_array(self.lead, (N_LEGS,), "lead"))
        put("sigma", _legs_array(self.sigma, (N_LEGS,), "sigma"))
        put("starts", _legs_array(self.starts, (N_LEGS,), "starts", dtype=int))
        put("gear_ratio", _legs_array(self.gear_ratio, (N_LEGS,), "gear_ratio"))
        if np.any(self.lead < 0):
            raise InputError("'lead' must be >= 0 (the thread hand goes into 'sigma')", source=_SOURCE,
                             field="lead")
        if not np.all(np.isin(self.sigma, (-1.0, 1.0))):
            raise InputError(f"'sigma' entries must be +1 or -1, got {self.sigma.tolist()}", source=_SOURCE,
                             field="sigma")
        if np.any(self.starts < 1):
            raise InputError("'starts' must be >= 1", source=_SOURCE, field="starts")
        if np.any(self.gear_ratio == 0):
            raise InputError("'gear_ratio' must be non-zero", source=_SOURCE, field="gear_ratio")
        if self.euler not in EULER_CONVENTIONS:
            raise InputError(f"unknown rotation convention '{self.euler}'; known: "
                             f"{', '.join(EULER_CONVENTIONS)}", source=_SOURCE, field="euler")
        if self.nut_side not in ("platform", "base"):
            raise InputError(f"'nut_side' must be 'platform' or 'base', got '{self.nut_side}'",
                             source=_SOURCE, field="nut_side")
        base_axes = self.b if self.base_axes is None else _legs_array(self.base_axes, (N_LEGS, 3), "base_axes")
        plat_axes = self.m if self.plat_axes is None else _legs_array(self.plat_axes, (N_LEGS, 3), "plat_axes")
        put("base_axes", _unit_rows(base_axes, "base_axes"))
        put("plat_axes", _unit_rows(plat_axes, "plat_axes"))

    # ---- derived values --------------------------------------------------------------
    @property
    def pitch(self) -> np.ndarray:
        """Thread pitch d = lead / starts, m."""
        return self.lead / self.starts

    @property
    def thread_hands(self) -> list[str]:
        return [thread_hand(s, self.nut_side) for s in self.sigma]

    @property
    def home_rotation(self) -> np.ndarray:
        return rotation_matrices(self.p0[3:], self.euler)

    def with_changes(self, **changes) -> "FloatingNutGeometry":
        """A copy with some fields replaced (validated again)."""
        return replace(self, **changes)

    @classmethod
    def from_azimuths(cls, base_radius: float, base_azimuths, plat_radius: float, plat_azimuths,
                      p0, base_height: float = 0.0, plat_height: float = 0.0, **kwargs
                      ) -> "FloatingNutGeometry":
        """Joints on two circles: radii in m, azimuths (6,) in rad, heights in m (z in each frame)."""
        def circle(radius, az, height, name):
            az = _legs_array(az, (N_LEGS,), name)
            if not radius > 0:
                raise InputError(f"radius must be positive, got {radius}", source=_SOURCE, field=name)
            return np.column_stack([radius * np.cos(az), radius * np.sin(az), np.full(N_LEGS, height)])
        return cls(b=circle(base_radius, base_azimuths, base_height, "base_azimuths"),
                   m=circle(plat_radius, plat_azimuths, plat_height, "plat_azimuths"), p0=p0, **kwargs)

    @classmethod
    def from_thread(cls, b, m, p0, starts=1, pitch=0.01, hand="left", nut_side="platform", **kwargs
                    ) -> "FloatingNutGeometry":
        """Geometry from thread data: lead = starts * pitch (m), sigma from hand and nut side."""
        starts_arr = _legs_array(starts, (N_LEGS,), "starts", dtype=int)
        pitch_arr = _legs_array(pitch, (N_LEGS,), "pitch")
        hands = [hand] * N_LEGS if isinstance(hand, str) else list(hand)
        if len(hands) != N_LEGS:
            raise InputError(f"'hand' needs one entry per leg ({N_LEGS}), got {len(hands)}", source=_SOURCE,
                             field="hand")
        sigma = [sigma_from_thread(h, nut_side) for h in hands]
        return cls(b=b, m=m, p0=p0, lead=starts_arr * pitch_arr, sigma=sigma, starts=starts_arr,
                   nut_side=nut_side, **kwargs)


def reference_fixture() -> FloatingNutGeometry:
    """The reference test fixture of docs/floating_nut_hexapod.md: radii 0.60 / 0.40 m, home height 0.80 m, lead 10 mm, sigma +1."""
    deg = np.deg2rad
    return FloatingNutGeometry.from_azimuths(
        0.60, deg([-10, 10, 110, 130, 230, 250]), 0.40, deg([-50, 50, 70, 170, 190, 290]),
        p0=[0, 0, 0.80, 0, 0, 0], lead=0.010, sigma=1, name="floating_nut_hexapod")


def tangent_basis(axes: np.ndarray) -> np.ndarray:
    """Two unit vectors perpendicular to each axis, chosen deterministically.

    axes: (n, 3) unit. Returns (n, 2, 3): small changes of an axis direction are
    delta = e1 * t1 + e2 * t2 (rad), the two calibration angles of a Hooke axis.
    """
    axes = np.asarray(axes, dtype=float)
    helper = np.where(np.abs(axes[:, [0]]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    e1 = np.cross(axes, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(axes, e1)
    return np.stack([e1, e2], axis=1)
