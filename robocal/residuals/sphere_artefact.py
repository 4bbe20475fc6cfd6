"""A multi-sphere artefact probed by a touch probe: sphere-centre distances and sphere radii.

One term = one placement of the artefact. It owns the probe hits (samples) on each of its S spheres,
fits a sphere to each sphere's tip-centre points (geometric least squares, robocal.residuals.sphere_fit) and
returns S(S-1)/2 + S rows:

    distance rows (j < m, lexicographic)  |c_j - c_m| - D_ref[j, m]
    radius rows (j)                       r_j - (r_ref[j] + tip_radius)

with their derivative with respect to the LOCAL twist of the probe frame at every hit (through the
analytic fit sensitivity). Works on any robot with a probe frame; rows of one kind can be switched off
(`use="distance"` or `"radius"`), which is how the constraints are used alone or combined.
Auxiliary: `<name>.radius.<j>`, `<name>.distance.<j>.<m>` (the artefact's certificate, known by default)
and `<name>.tip_radius` (known by default; free it to estimate an effective tip radius).
"""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError
from robocal.residuals.sphere_fit import fit_sphere, sphere_fit_sensitivity
from robocal.residuals.base import Aux, Residual, Term, point_jacobian


def pair_indices(n_spheres: int) -> list[tuple[int, int]]:
    return [(j, m) for j in range(n_spheres) for m in range(j + 1, n_spheres)]


def artefact_rows(points: list[np.ndarray], distances: np.ndarray, radii: np.ndarray, tip_radius: float,
                  source: str = "placement"):
    """Rows of one placement and their derivative with respect to the points.

    points: S arrays (N_j, 3) of tip centres. Returns rows (S(S-1)/2 + S,), dR/dX (rows, 3 sum N_j) over
    the points stacked sphere by sphere, and the S SphereFit results.
    """
    S = len(points)
    fits, sens = [], []
    for j, X in enumerate(points):
        f = fit_sphere(X, source=f"{source}, sphere {j}")
        fits.append(f)
        sens.append(sphere_fit_sensitivity(X, f.centre, f.radius))
    pairs = pair_indices(S)
    starts = np.concatenate([[0], np.cumsum([3 * len(X) for X in points])])
    rows = np.empty(len(pairs) + S)
    D = np.zeros((len(pairs) + S, starts[-1]))
    for k, (j, m) in enumerate(pairs):
        w = fits[j].centre - fits[m].centre
        dist = np.linalg.norm(w)
        rows[k] = dist - distances[j, m]
        wh = w / dist
        D[k, starts[j]:starts[j + 1]] = wh @ sens[j][:3]
        D[k, starts[m]:starts[m + 1]] = -wh @ sens[m][:3]
    for j in range(S):
        rows[len(pairs) + j] = fits[j].radius - (radii[j] + tip_radius)
        D[len(pairs) + j, starts[j]:starts[j + 1]] = sens[j][3]
    return rows, D, fits


class SphereArtefactResidual(Residual):
    """placements: per placement, per sphere, the sample indices of its hits (>= 4, not coplanar).

    radii (S,) and distances (S, S) are the reference (certificate) values, SI. `frame`/`point`: the
    probe tip centre on the robot. sigma_distance / sigma_radius: row standard deviations (m).
    use: "both", "distance" or "radius".
    """

    type_name = "sphere_artefact"
    observed = False

    def __init__(self, name, frame, placements, radii, distances, tip_radius=0.0, point=(0.0, 0.0, 0.0),
                 sigma_distance=1e-6, sigma_radius=1e-6, use="both", tip_radius_unknown=False):
        radii = np.asarray(radii, dtype=float).reshape(-1)
        self.n_spheres = S = len(radii)
        distances = np.asarray(distances, dtype=float)
        if S < 2 or distances.shape != (S, S):
            raise InputError(f"residual '{name}': need >= 2 spheres and an (S, S) distance matrix, got "
                             f"{S} radii and distances of shape {distances.shape}", field="distances")
        self.placements = [[np.asarray(h, dtype=int).reshape(-1) for h in plc] for plc in placements]
        for g, plc in enumerate(self.placements):
            if len(plc) != S:
                raise InputError(f"residual '{name}': placement {g} has {len(plc)} spheres, the artefact {S}",
                                 field="placements")
            for j, h in enumerate(plc):
                if len(h) < 4:
                    raise InputError(f"residual '{name}': placement {g}, sphere {j} has {len(h)} hits; "
                                     "a sphere fit needs at least 4", field="placements")
        if use not in ("both", "distance", "radius"):
            raise InputError(f"residual '{name}': use must be both, distance or radius, got '{use}'", field="use")
        n_pairs = S * (S - 1) // 2
        sigma = np.concatenate([np.full(n_pairs, sigma_distance), np.full(S, sigma_radius)])
        weights = np.concatenate([np.full(n_pairs, float(use != "radius")), np.full(S, float(use != "distance"))])
        flat = np.concatenate([h for plc in self.placements for h in plc]) if self.placements else np.zeros(0, int)
        super().__init__(name, flat, sigma, weights)
        self.frame = frame
        self.point = np.asarray(point, dtype=float).reshape(3)
        self.pairs = pair_indices(S)
        self.aux = ([Aux(f"radius.{j}", float(radii[j]), "m", False) for j in range(S)]
                    + [Aux(f"distance.{j}.{m}", float(distances[j, m]), "m", False) for j, m in self.pairs]
                    + [Aux("tip_radius", float(tip_radius), "m", bool(tip_radius_unknown))])

    @property
    def dim(self) -> int:
        return self.n_spheres * (self.n_spheres - 1) // 2 + self.n_spheres

    @property
    def row_units(self):
        return ("length",) * self.dim

    @property
    def n_terms(self) -> int:
        return len(self.placements)

    def term_samples(self, k: int) -> tuple[int, ...]:
        return tuple(int(i) for h in self.placements[k] for i in h)

    def evaluate(self, k, states, aux):
        S, n_pairs = self.n_spheres, len(self.pairs)
        radii = aux[:S]
        D = np.zeros((S, S))
        for (j, m), v in zip(self.pairs, aux[S:S + n_pairs]):
            D[j, m] = D[m, j] = v
        pts, jacs, ids = [], [], []
        for h in self.placements[k]:
            Ms = [states[i].pose(self.frame) for i in h]
            pts.append(np.array([M.act(self.point) for M in Ms]))
            jacs += [point_jacobian(M, self.point) for M in Ms]
            ids += [int(i) for i in h]
        rows, dX, _ = artefact_rows(pts, D, radii, aux[-1], source=f"residual '{self.name}', placement {k}")
        frames = [(i, self.frame, dX[:, 3 * n:3 * n + 3] @ Jp) for n, (i, Jp) in enumerate(zip(ids, jacs))]
        return Term(rows, frames, self.certificate_jacobian())

    def certificate_jacobian(self) -> np.ndarray:
        """(dim, S + S(S-1)/2 + 1) derivative of a term's rows with respect to the certificate's radii and
        distances and the tip radius (the auxiliaries in their order)."""
        S, n_pairs = self.n_spheres, len(self.pairs)
        A = np.zeros((self.dim, S + n_pairs + 1))
        A[n_pairs:, :S] = -np.eye(S)
        A[:n_pairs, S:S + n_pairs] = -np.eye(n_pairs)
        A[n_pairs:, -1] = -1.0
        return A
