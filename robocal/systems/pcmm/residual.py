"""The 4-PUU CMM's sphere-artefact residual, with its tip points from the machine's closed form.

Rows as robocal.residuals.sphere_artefact (per placement of the artefact: S(S-1)/2 centre distances, then
S radii, through the analytic sphere-fit sensitivity), but the probe tip centres and their sensitivity to
the machine come from robocal.systems.pcmm.kinematics (Newton FK batched over every hit, J_p = J_q^-1 J_eps)
rather than from the URDF's closed-chain assembly: one evaluation of the reference design's 288 hits costs
milliseconds instead of most of a second (benchmarks/pcmm_calibration.py prints both). The closed form
is therefore the engine, and the machine's 32 reduced parameters are this residual's own unknowns:
auxiliary parameters named like the reduced parameters (`limb1.ax` ... `limb4.l`; value = deviation
from the nominal machine, m or rad), shared by every residual built on the same nominal machine. The
artefact's certificate (radii, distances) and the tip radius are the auxiliaries of SphereArtefactResidual.

A sphere flagged as mis-triggered (`excluded`, (placement, sphere) pairs) is left out of its placement's
fits; its rows are zero with no derivative, since the generic layer keeps a fixed number of rows per term.
See docs/pcmm_calibration.md.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.residuals.sphere_fit import fit_sphere
from robocal.model.parameters import Parameter
from robocal.residuals.base import Term
from robocal.residuals.sphere_artefact import SphereArtefactResidual, artefact_rows
from robocal.systems.pcmm.kinematics import (N_REDUCED, PCMMGeometry, forward_kinematics,
                                             reduced_names, tip_error_jacobian, tip_points, tip_reading_jacobian)
from robocal.systems.pcmm.machine import Artefact, ProbeHits

ANGLE_FIELDS = ("alpha", "beta")


@dataclass
class HitKinematics:
    """Closed-form state of every hit for one machine: poses (N, 4), tips (N, 3), tip Jacobian (N, 3, 32)."""

    key: bytes
    geometry: PCMMGeometry
    poses: np.ndarray
    tips: np.ndarray
    tip_jacobian: np.ndarray


def machine_parameters(vary: bool = True) -> list[Parameter]:
    """The 32 reduced parameters as deviations from the nominal machine (0 = nominal), reduced order."""
    return [Parameter(name, "auxiliary", "pcmm", k, value=0.0, vary=vary,
                      unit="rad" if name.split(".")[1] in ANGLE_FIELDS else "m")
            for k, name in enumerate(reduced_names())]


class PCMMArtefactResidual(SphereArtefactResidual):
    """Probe hits of a 4-PUU CMM on a multi-sphere artefact.

    nominal: the machine the parameters deviate from; hits: readings (N, 4) with their placement and
    sphere (their sample indices in the problem are 0..N-1, the rows of hits.readings); artefact: the
    certificate. sigma_distance / sigma_radius: row standard deviations (m); use: "both", "distance" or
    "radius"; excluded: (placement, sphere) pairs left out.
    """

    type_name = "pcmm_sphere_artefact"

    def __init__(self, name: str, nominal: PCMMGeometry, hits: ProbeHits, artefact: Artefact,
                 sigma_distance: float = 1e-6, sigma_radius: float = 1e-6, use: str = "both", excluded=()):
        super().__init__(name, "probe_tip", hits.groups(), artefact.radii, artefact.distances,
                         tip_radius=nominal.tip_radius, sigma_distance=sigma_distance, sigma_radius=sigma_radius,
                         use=use)
        self.nominal = nominal
        self.readings = np.asarray(hits.readings, dtype=float).reshape(-1, 4)
        self.excluded = frozenset(excluded) | frozenset(getattr(hits, "excluded", ()) or ())
        self.n_certificate = len(self.aux)
        # FK starts at the home height with the commanded rotation; later calls start at the last solution
        self.start = np.column_stack([np.broadcast_to(nominal.home[:3], (len(self.readings), 3)), hits.theta_cmd])
        self.last: HitKinematics | None = None
        self.terms_key, self.terms = b"", {}     # the terms of the last parameter vector evaluated

    def aux_parameters(self) -> list[Parameter]:
        return super().aux_parameters() + machine_parameters()

    def machine_parameter_names(self) -> list[str]:
        return [p.name for p in machine_parameters()]     # the 32 reduced error parameters are the machine

    def machine(self, aux: np.ndarray) -> PCMMGeometry:
        return self.nominal.perturbed(np.asarray(aux)[self.n_certificate:])

    def kinematics(self, aux: np.ndarray) -> HitKinematics:
        """FK, tips and tip Jacobian of every hit for the machine of `aux` (computed once per machine)."""
        eps = np.ascontiguousarray(np.asarray(aux, dtype=float)[self.n_certificate:])
        key = eps.tobytes()
        if self.last is not None and self.last.key == key:
            return self.last
        geo = self.nominal.perturbed(eps)
        Y, _ = forward_kinematics(geo, self.readings, self.start if self.last is None else self.last.poses)
        self.last = HitKinematics(key, geo, Y, tip_points(geo, Y), tip_error_jacobian(geo, Y, self.readings))
        return self.last

    def present(self, k: int) -> list[int]:
        return [j for j in range(self.n_spheres) if (k, j) not in self.excluded]

    def row_kinds(self) -> np.ndarray:
        """(dim,) 'distance' or 'radius' of each row of a term."""
        return np.array(["distance"] * len(self.pairs) + ["radius"] * self.n_spheres)

    def live_rows(self, k: int) -> np.ndarray:
        """(dim,) False for the rows of term k that involve an excluded sphere."""
        present = set(self.present(k))
        return np.array([j in present and m in present for j, m in self.pairs]
                        + [j in present for j in range(self.n_spheres)])

    def _placement_rows(self, k: int, aux: np.ndarray, tips: np.ndarray):
        """Rows of term k (dim,), dR/dX over the present spheres' hits, the row and hit indices used."""
        S, n_pairs = self.n_spheres, len(self.pairs)
        present = self.present(k)
        D = np.zeros((S, S))
        for (j, m), v in zip(self.pairs, aux[S:S + n_pairs]):
            D[j, m] = D[m, j] = v
        rows, dX, _ = artefact_rows([tips[self.placements[k][j]] for j in present], D[np.ix_(present, present)],
                                    aux[:S][present], aux[S + n_pairs],
                                    source=f"residual '{self.name}', placement {k}")
        used = np.flatnonzero(self.live_rows(k))    # the present spheres' rows, in artefact_rows' order
        hits = np.concatenate([self.placements[k][j] for j in present])
        r = np.zeros(self.dim)
        r[used] = rows
        return r, dX, used, hits

    def evaluate(self, k, states, aux):
        key = np.asarray(aux, dtype=float).tobytes()
        if key != self.terms_key:     # a calibration evaluates its start twice (warnings, then the fit)
            self.terms_key, self.terms = key, {}
        if k not in self.terms:
            kin = self.kinematics(aux)
            r, dX, used, hits = self._placement_rows(k, aux, kin.tips)
            A = np.zeros((self.dim, len(aux)))
            A[:, :self.n_certificate] = self.certificate_jacobian()
            A[~self.live_rows(k), :self.n_certificate] = 0.0
            A[used, self.n_certificate:] = dX @ kin.tip_jacobian[hits].reshape(-1, N_REDUCED)
            self.terms[k] = Term(r, [], A)
        return self.terms[k]

    def reading_jacobian(self, aux: np.ndarray) -> np.ndarray:
        """(n_terms * dim, 4 N) derivative of every row (unscaled) with respect to the axis readings."""
        kin = self.kinematics(aux)
        TR = tip_reading_jacobian(kin.geometry, kin.poses, self.readings)
        out = np.zeros((self.n_terms * self.dim, 4 * len(self.readings)))
        for k in range(self.n_terms):
            _, dX, used, hits = self._placement_rows(k, aux, kin.tips)
            dR = np.einsum("rna,nab->rnb", dX.reshape(len(used), len(hits), 3), TR[hits])   # (rows, hits, 4)
            cols = (4 * hits[:, None] + np.arange(4)).reshape(-1)
            out[np.ix_(k * self.dim + used, cols)] = dR.reshape(len(used), -1)
        return out

    def fit_rms(self, aux: np.ndarray) -> np.ndarray:
        """(placements, spheres) RMS of each sphere fit (m); NaN for excluded spheres."""
        tips = self.kinematics(aux).tips
        out = np.full((self.n_terms, self.n_spheres), np.nan)
        for k, placement in enumerate(self.placements):
            for j in self.present(k):
                out[k, j] = fit_sphere(tips[placement[j]], source=f"placement {k}, sphere {j}").rms
        return out

