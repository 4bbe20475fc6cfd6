"""What a real 4-PUU CMM calibration meets that its 32-parameter simulation leaves out: certificate error, probe pre-travel, bowed columns.

docs/pcmm_calibration.md, "Under realistic conditions": the artefact's certificate has errors, the touch
probe triggers after a pre-travel that depends on the approach direction, and the columns are not straight.

* `certificate`: the sphere distances and radii the reference CMM certified, i.e. the true ones plus its
  error (independent per distance and per radius, Gaussian). The calibration uses the certificate.
* `PreTravel`: the probe triggers `mean + lobe * sin(polar) * cos(lobes * azimuth)` after first contact,
  along the approach normal, azimuth measured in the probe's own frame (it turns with theta): the machine
  reads the tip centre that much inside the sphere. Qualifying the probe on a reference sphere gives the
  effective tip radius r_tip - mean (`qualified_tip_radius`); the lobing stays.
* `BowedColumns`: the slider of limb i leaves its straight axis by a bow w_i(p) = amplitude_i (1 - ((p - c)
  / h)^2) along the column's radial direction, p the axis reading (zero at c +- h, the travel's ends). A
  quadratic in p is outside the 32-parameter model (straight axes), which is the point.
Units: SI (m, rad).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from robocal.errors import AssemblyError
from robocal.systems.pcmm.kinematics import PCMMGeometry, axis_directions, inverse_kinematics, rz, tip_points
from robocal.systems.pcmm.machine import Artefact


def certificate(true: Artefact, rng: np.random.Generator, sigma_distance: float, sigma_radius: float) -> Artefact:
    """The certificate of the artefact `true`: its distances and radii with the reference CMM's error."""
    S = true.n_spheres
    err = np.triu(rng.normal(0.0, sigma_distance, (S, S)), 1)
    return replace(true, radii=true.radii + rng.normal(0.0, sigma_radius, S), distances=true.distances + err + err.T)


@dataclass(frozen=True)
class PreTravel:
    """Trigger delay of a touch probe (m) by approach direction: mean + lobe sin(polar) cos(lobes azimuth)."""

    mean: float = 0.0
    lobe: float = 0.0
    lobes: int = 3

    def __call__(self, normals_probe: np.ndarray) -> np.ndarray:
        """(N,) pre-travel for outward surface normals (N, 3) expressed in the probe frame."""
        n = np.asarray(normals_probe, dtype=float).reshape(-1, 3)
        polar_sin = np.hypot(n[:, 0], n[:, 1])
        return self.mean + self.lobe * polar_sin * np.cos(self.lobes * np.arctan2(n[:, 1], n[:, 0]))

    def qualified_tip_radius(self, tip_radius: float) -> float:
        """What qualifying the probe on a reference sphere gives: the tip radius less the mean pre-travel."""
        return tip_radius - self.mean


@dataclass(frozen=True)
class BowedColumns:
    """A reduced machine whose column i is bowed by amplitude[i] (m) over the readings c +- h."""

    geometry: PCMMGeometry
    amplitude: np.ndarray
    centre: float = -0.075
    half_range: float = 0.225

    @property
    def tip_radius(self) -> float:
        return self.geometry.tip_radius

    @property
    def stylus(self) -> np.ndarray:
        return self.geometry.stylus

    def radial(self) -> np.ndarray:
        """(4, 3) the horizontal direction from the machine's axis out to each column, normal to its axis."""
        e = axis_directions(self.geometry.tilts)[0]
        r = self.geometry.columns * np.array([1.0, 1.0, 0.0])
        r = r - np.sum(r * e, axis=1, keepdims=True) * e
        return r / np.linalg.norm(r, axis=1, keepdims=True)

    def bow(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """w (N, 4) and dw/dp (N, 4) at readings p (N, 4)."""
        x = (p - self.centre) / self.half_range
        a = np.asarray(self.amplitude, dtype=float)
        return a * (1.0 - x * x), a * (-2.0 * x / self.half_range)

    def readings(self, Y, iterations: int = 8) -> np.ndarray:
        """Axis readings (N, 4) that put the bowed machine at poses Y (N, 4): Newton on each limb's loop
        |q + R b_i - A_i - p e_i - w_i(p) n_i| = l_i from the straight machine's readings."""
        geo = self.geometry
        Y = np.asarray(Y, dtype=float).reshape(-1, 4)
        p = inverse_kinematics(geo, Y)
        E = Y[:, None, :3] + np.einsum("nab,ib->nia", rz(Y[:, 3]), geo.platform_joints) - geo.columns[None]
        e, n = axis_directions(geo.tilts)[0], self.radial()
        for _ in range(iterations):
            w, dw = self.bow(p)
            v = E - p[:, :, None] * e[None] - w[:, :, None] * n[None]
            f = np.sum(v * v, axis=2) - geo.lengths ** 2
            df = -2.0 * np.sum(v * (e[None] + dw[:, :, None] * n[None]), axis=2)
            p = p - f / df
        w, _ = self.bow(p)
        v = E - p[:, :, None] * e[None] - w[:, :, None] * n[None]
        miss = np.abs(np.linalg.norm(v, axis=2) - geo.lengths).max()
        if not miss < 1e-12:
            raise AssemblyError(f"bowed-column IK did not close its loops (miss {miss:.2e} m)")
        return p

    def tips(self, Y) -> np.ndarray:
        return tip_points(self.geometry, Y)


def bowed_readings(machine: BowedColumns, Y) -> np.ndarray:
    """`validate`'s true_ik for a bowed machine."""
    return machine.readings(Y)
