"""The 4-PUU CMM's error model: 52 raw error sources, their exact reduction to 32, and the gauge.

Raw sources per limb (13 each; docs/pcmm_calibration.md): column point a_i (3), axis tilts alpha_i,
beta_i (2), slider zero offset p0_i (1), slider-side Hooke joint offset d_i (3), link length l_i (1),
platform joint b_i (3).
The readings are physical slider travel minus p0_i. The reduction is exact, not first order:
a_i, d_i and p0_i e_i are constant vectors that only ever appear summed, A_i = a_i + d_i + p0_i e_i, and the
z part of that sum only appears together with b_iz (Rz keeps z), so A_iz - A_iz,nominal moves into b_iz:
b_iz' = b_iz - (A_iz - A_iz,nominal).

Gauge (docs/pcmm_calibration.md): distances and radii of a probed artefact are blind to five directions of the 32:
base translation x, y, z; base rotation about z; and the moving frame's theta zero (b_i rotated about z
about the stylus axis, b_i - t -> Rz(psi)(b_i - t), which leaves every tip point where it was).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.systems.pcmm.kinematics import N_LIMBS, PCMMGeometry, axis_directions, rz

RAW_FIELDS = ("ax", "ay", "az", "alpha", "beta", "p0", "dx", "dy", "dz", "l", "bx", "by", "bz")
N_RAW = N_LIMBS * len(RAW_FIELDS)
GAUGE_NAMES = ("base translation x", "base translation y", "base translation z", "base rotation z",
               "theta zero")


def raw_names() -> list[str]:
    return [f"limb{i + 1}.{f}" for i in range(N_LIMBS) for f in RAW_FIELDS]


@dataclass(frozen=True)
class RawPCMM:
    """The machine with every raw error source explicit (SI). Readings = physical travel - p0."""

    a: np.ndarray        # (4, 3) column foot points
    tilts: np.ndarray    # (4, 2) (alpha, beta)
    p0: np.ndarray       # (4,) slider zero offsets
    d: np.ndarray        # (4, 3) slider point -> Hooke joint D
    lengths: np.ndarray  # (4,)
    b: np.ndarray        # (4, 3) platform joints, moving frame
    stylus: np.ndarray
    tip_radius: float
    home: np.ndarray

    def raw_vector(self) -> np.ndarray:
        return np.column_stack([self.a, self.tilts, self.p0, self.d, self.lengths, self.b]).reshape(-1)

    def with_raw(self, x) -> "RawPCMM":
        x = np.asarray(x, dtype=float).reshape(N_LIMBS, len(RAW_FIELDS))
        return RawPCMM(x[:, 0:3], x[:, 3:5], x[:, 5], x[:, 6:9], x[:, 9], x[:, 10:13], self.stylus,
                       self.tip_radius, self.home)


def raw_from_reduced(geo: PCMMGeometry, d: np.ndarray) -> RawPCMM:
    """A raw description of a reduced machine with the given Hooke-joint offsets d (4, 3) and p0 = 0."""
    d = np.asarray(d, dtype=float).reshape(4, 3)
    return RawPCMM(geo.columns - d, geo.tilts.copy(), np.zeros(4), d, geo.lengths.copy(),
                   geo.platform_joints.copy(), geo.stylus.copy(), geo.tip_radius, geo.home.copy())


def raw_inverse_kinematics(raw: RawPCMM, Y) -> np.ndarray:
    """Readings (N, 4) of the raw model, written independently of the reduced one (eq. 1-2 as printed)."""
    Y = np.asarray(Y, dtype=float).reshape(-1, 4)
    e = axis_directions(raw.tilts)[0]
    out = np.empty((len(Y), 4))
    for n, y in enumerate(Y):
        R = rz(y[3])
        for i in range(4):
            E = y[:3] + R @ raw.b[i] - raw.a[i] - raw.d[i]
            s = e[i] @ E
            out[n, i] = s + np.sqrt(s * s - E @ E + raw.lengths[i] ** 2) - raw.p0[i]
    return out


def reduce(raw: RawPCMM, nominal: PCMMGeometry) -> PCMMGeometry:
    """The exact 32-parameter machine of a raw one; A_z stays at `nominal`'s value (its change goes to b_z)."""
    e = axis_directions(raw.tilts)[0]
    A = raw.a + raw.d + raw.p0[:, None] * e
    b = raw.b.copy()
    b[:, 2] -= A[:, 2] - nominal.columns[:, 2]
    A[:, 2] = nominal.columns[:, 2]
    return PCMMGeometry(A, raw.tilts, b, raw.lengths, raw.stylus, raw.tip_radius, raw.home)


def random_raw_errors(nominal: RawPCMM, rng: np.random.Generator, scale: float = 1.0) -> RawPCMM:
    """Truth for tests (the reference run of docs/pcmm_calibration.md): Gaussian errors a 0.3 mm, tilts
    0.5 mrad, p0 0.3 mm, d 0.2 mm, b 0.2 mm, l 0.3 mm, times `scale`."""
    sig = np.array([3e-4] * 3 + [5e-4] * 2 + [3e-4] + [2e-4] * 3 + [3e-4] + [2e-4] * 3)
    return nominal.with_raw(nominal.raw_vector() + scale * rng.normal(0.0, np.tile(sig, N_LIMBS)))


def gauge_vectors(geo: PCMMGeometry) -> np.ndarray:
    """(5, 32) unit directions of the reduced parameters that no distance or radius can see.

    Exact at zero tilts (the nominal machine); to first order elsewhere. Order: GAUGE_NAMES.
    """
    g = np.zeros((5, N_LIMBS, 8))
    A, b, t = geo.columns, geo.platform_joints, geo.stylus
    al, be = geo.tilts[:, 0], geo.tilts[:, 1]
    g[0, :, 0] = 1.0                      # every column point moves +x
    g[1, :, 1] = 1.0
    g[2, :, 6] = -1.0                     # columns up = platform joints down (A_z merged into b_z)
    g[3, :, 0], g[3, :, 1] = -A[:, 1], A[:, 0]   # columns rotate about z ...
    g[3, :, 2], g[3, :, 3] = al, -be      # ... and so do tilted axes (de = z x e)
    g[4, :, 4], g[4, :, 5] = -(b[:, 1] - t[1]), b[:, 0] - t[0]   # b_i - t rotates about z
    g = g.reshape(5, -1)
    return g / np.linalg.norm(g, axis=1, keepdims=True)
