"""Self-calibration of the 4-PUU parallel CMM from a multi-sphere artefact, through the generic layer.

The probe hits become a robocal Problem with one residual plug-in, PCMMArtefactResidual (sphere-centre
distance and radius errors, tip points from the closed-form kinematics), and robocal.estimation.calibrate
identifies the machine's 32 reduced parameters with the generic Levenberg-Marquardt and statistics.

Gauge: distances and radii are blind to five directions of the 32 (base translation x, y, z, base rotation
z, theta zero; robocal.systems.pcmm.error_model.gauge_vectors). Two treatments, both generic:
gauge="fix" (default) holds five parameters at their nominal value as constraints: the five that
column-pivoted QR of the scaled Jacobian leaves out are put last in the order, and the generic
base-parameter selection, which drops the later of two parameters it cannot tell apart, holds them and
reports what each is confounded with. gauge="prior" puts a weak prior (GAUGE_SIGMA = 1 km or 1000 rad, 1e9
times the rows' sigma) on every parameter: the data decide the 27 directions they see and the prior picks,
along the five blind ones, the machine nearest the nominal (the minimum-norm choice); the result names five
parameters as determined by their priors only. Either way the fit is one representative of the gauge
class, and every gauge-invariant figure (distances, rigidly aligned tip errors) is the same.
Acquisition warnings use the same selection: exact rank, and an effective rank that also counts as missing
the directions too weak to be useful. Units: SI (m, rad). See docs/pcmm_calibration.md.
"""
from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from robocal.errors import InputError
from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.identifiability import BaseSelection, select_base_parameters
from robocal.estimation.problem import Problem
from robocal.estimation.result import CalibrationResult
from robocal.model.parameters import ParameterSet
from robocal.systems.pcmm.kinematics import N_REDUCED, PCMMGeometry, reduced_names
from robocal.systems.pcmm.machine import Artefact, ProbeHits, machine_robot
from robocal.systems.pcmm.residual import PCMMArtefactResidual

log = logging.getLogger(__name__)
EXPECTED_RANK = 27       # 32 reduced parameters minus 5 gauge directions
RESIDUAL = "artefact"
ROW_SIGMA = 1e-6         # m, default standard deviation of a distance or radius row
GAUGE_SIGMA = 1e3        # m or rad: the weak prior of gauge="prior" (1 m biased a noise-free fit by ~1e-14 m)
GAUGES = ("fix", "prior")
# A scaled singular value below WEAK_RTOL x the largest counts as missing in the effective rank. Heuristic
# from the reference design: with theta varied by +-0.3 rad the 27th scaled singular value is ~2e-3 of the
# largest; with theta fixed the 18th falls to ~5e-4 (docs/pcmm_calibration.md).
WEAK_RTOL = 1e-3


class AcquisitionWarning(UserWarning):
    """The probing design cannot determine every identifiable parameter."""


@dataclass
class PCMMCalibration:
    """A PCMM self-calibration: the identified machine and the generic result behind it."""

    nominal: PCMMGeometry
    geometry: PCMMGeometry               # identified
    d_eps: np.ndarray                    # (32,) identified - nominal, order of `names` (0 for the gauge)
    names: list[str]
    result: CalibrationResult            # the generic fit: selection, covariance, convergence record
    problem: Problem
    poses: np.ndarray                    # (N, 4) platform poses of the hits on the identified machine
    rms_before: dict                     # residual RMS (m) by kind: all, distance, radius
    rms_after: dict
    flagged: list = field(default_factory=list)     # [(placement, sphere, fit RMS m)]
    warnings: list = field(default_factory=list)

    @property
    def converged(self) -> bool:
        return self.result.solve.success

    @property
    def message(self) -> str:
        return self.result.solve.message

    @property
    def history(self) -> list:
        return self.result.solve.history

    @property
    def rank(self) -> int:
        """Directions the data determine (the selection's rank, less the parameters kept by a prior alone)."""
        return self.result.selection.rank - len(self.result.prior_only)

    @property
    def singular_values(self) -> np.ndarray:
        """Of the column-scaled Jacobian at the start (largest first)."""
        return self.result.selection.singular_values

    @property
    def gauge(self) -> list[str]:
        """The five parameters standing for the gauge: held at nominal ("fix") or set by their prior."""
        return self.result.unidentifiable or self.result.prior_only


def pcmm_problem(nominal: PCMMGeometry, hits: ProbeHits, artefact: Artefact, use: str = "both",
                 sigma: float = ROW_SIGMA, excluded=(), gauge_sigma: float | None = None) -> Problem:
    """The generic problem of the hits: the machine `nominal` (its URDF, in memory), the 32 reduced
    parameters free at 0 (= nominal), one PCMMArtefactResidual; with gauge_sigma, a prior of that sigma
    (mean 0) on each parameter."""
    robot = machine_robot(nominal)
    res = PCMMArtefactResidual(RESIDUAL, nominal, hits, artefact, sigma, sigma, use, excluded)
    problem = Problem(robot, ParameterSet(), robot.loops.actuated, hits.readings, [res])
    if gauge_sigma is not None:
        for name in reduced_names():
            problem.params[name].prior_sigma = gauge_sigma
    return problem


def artefact_residual(problem: Problem) -> PCMMArtefactResidual:
    return problem.residuals[0]


def measurement_rows(problem: Problem) -> slice:
    """The artefact's rows in the problem's residual vector (prior rows, if any, follow them)."""
    return next(b.rows for b in problem.blocks if b.name == RESIDUAL)


def problem_geometry(problem: Problem) -> PCMMGeometry:
    """The machine at the problem's current parameter values."""
    return artefact_residual(problem).machine(problem.aux_values(artefact_residual(problem)))


def reduced_columns(problem: Problem) -> np.ndarray:
    """Indices of the 32 reduced parameters (reduced order) among problem.params.free_names."""
    free = problem.params.free_names
    return np.array([free.index(n) for n in reduced_names()])


def rms_by_kind(problem: Problem, scaled_rows: np.ndarray) -> dict:
    """RMS (m) of the measured rows, all and per kind, from the problem's scaled residual vector."""
    res = artefact_residual(problem)
    keep = res.row_scale() != 0
    raw = (scaled_rows[measurement_rows(problem)].reshape(res.n_terms, -1) / res.row_scale()[keep]).reshape(-1)
    kinds = np.tile(res.row_kinds()[keep], res.n_terms)
    live = np.concatenate([res.live_rows(k)[keep] for k in range(res.n_terms)])
    out = {"all": float(np.sqrt(np.mean(raw[live] ** 2)))}
    for kind in ("distance", "radius"):
        sel = live & (kinds == kind)
        if sel.any():
            out[kind] = float(np.sqrt(np.mean(raw[sel] ** 2)))
    return out


# ---- identifiability and acquisition warnings ------------------------------------------------
def effective_rank(selection: BaseSelection, weak_rtol: float = WEAK_RTOL) -> int:
    """Column-scaled singular values above weak_rtol x the largest (directions strong enough to use)."""
    s = selection.singular_values
    return int(np.sum(s > weak_rtol * s[0])) if s.size and s[0] > 0 else 0


def acquisition_warnings(J: np.ndarray, poses: np.ndarray, rank_rtol: float = 1e-8) -> list[str]:
    """Warnings about a probing design from its Jacobian J (M, 32) and the hits' platform poses."""
    sel = select_base_parameters(J, reduced_names(), rank_rtol)
    eff = effective_rank(sel)
    msgs = []
    if len(J) < EXPECTED_RANK:
        msgs.append(f"too few equations: {len(J)} distance/radius rows for {EXPECTED_RANK} identifiable parameters "
                    f"({N_REDUCED} minus 5 gauge directions); probe more artefact placements")
    if eff < EXPECTED_RANK:
        spread = float(np.ptp(poses[:, 3]))
        cause = ""
        if spread < 0.05:
            cause = (f" The platform rotation was not varied while probing (theta spread {spread:.3g} rad): "
                     "vary theta from hit to hit (e.g. +-0.3 rad) to observe the platform joints.")
        msgs.append(f"the design determines only {eff} of the {EXPECTED_RANK} identifiable parameter "
                    f"combinations (effective rank of the column-scaled Jacobian; exact rank {sel.rank} of "
                    f"{N_REDUCED}).{cause}")
    for m in msgs:
        log.warning(m)
        warnings.warn(m, AcquisitionWarning, stacklevel=3)
    return msgs


def check_acquisition(nominal: PCMMGeometry, hits: ProbeHits, artefact: Artefact, use: str = "both") -> list[str]:
    """Warnings about the probing design (issued as AcquisitionWarning and returned as text)."""
    problem = pcmm_problem(nominal, hits, artefact, use)
    J = problem.evaluate().J[:, reduced_columns(problem)]   # no priors: every row is a measurement
    return acquisition_warnings(J, artefact_residual(problem).last.poses)


# ---- identify ------------------------------------------------------------------------------------
def screen_spheres(fit_rms: np.ndarray, factor: float = 5.0, floor: float = 1e-7) -> list[tuple[int, int, float]]:
    """Spheres whose fit RMS stands out: (placement, sphere, RMS m) above max(factor x robust scale, floor);
    the floor keeps a noise-free fit from flagging anything."""
    rms = np.nan_to_num(fit_rms, nan=0.0)
    scale = 1.4826 * np.median(fit_rms[np.isfinite(fit_rms)])
    limit = max(factor * scale, floor)
    return [(int(g), int(j), float(rms[g, j])) for g, j in np.argwhere(rms > limit)]


def gauge_last(J: np.ndarray, rtol: float = 1e-8) -> list[str]:
    """Names of the reduced parameters that column-pivoted QR of the column-scaled J (M, 32) leaves out:
    held last in the order, they are the ones the generic selection attributes the gauge to."""
    norms = np.linalg.norm(J, axis=0)
    _, R, piv = scipy.linalg.qr(J / np.where(norms > 0, norms, 1.0), mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    k = int(np.sum(d > rtol * d[0]))
    names = reduced_names()
    return [names[i] for i in sorted(piv[k:])]


def _fit(problem: Problem, options: CalibrationOptions | None):
    """Acquisition warnings and rms before, the generic fit, rms after."""
    ev0 = problem.evaluate()
    J = ev0.J[measurement_rows(problem)][:, reduced_columns(problem)]
    msgs = acquisition_warnings(J, artefact_residual(problem).last.poses)
    # The selection walks the parameters in order and drops the later of two it cannot tell apart; left in
    # the reduced order it would hold limb3.ay and four limb4 parameters, a slice of the gauge class on
    # which LM needed 37 iterations instead of 5 on the reference run. QR picks a better-conditioned one.
    last = set(gauge_last(J))
    problem.params.reorder(lambda p: p.name in last)
    result = calibrate(problem, options, source="PCMM probe hits")
    return msgs, rms_by_kind(problem, ev0.r), result, rms_by_kind(problem, result.solve.fun)


def calibrate_pcmm(nominal: PCMMGeometry, hits: ProbeHits, artefact: Artefact, use: str = "both",
                   sigma: float = ROW_SIGMA, gauge: str = "fix", screen: bool = False, screen_factor: float = 5.0,
                   screen_floor: float = 1e-7, options: CalibrationOptions | None = None) -> PCMMCalibration:
    """Identify the 32 reduced parameters from probe hits on the artefact, starting from `nominal`.

    use: "both", "distance" or "radius" rows; sigma: their standard deviation (m); gauge: "fix" or "prior"
    (module doc); screen: flag spheres with a mis-triggered hit (fit RMS above screen_factor x the robust
    scale of all fits, and above screen_floor) and identify again without them; options: the generic
    solver's."""
    if gauge not in GAUGES:
        raise InputError(f"gauge must be one of {', '.join(GAUGES)}, got '{gauge}'", field="gauge")
    gauge_sigma = GAUGE_SIGMA if gauge == "prior" else None
    problem = pcmm_problem(nominal, hits, artefact, use, sigma, gauge_sigma=gauge_sigma)
    msgs, rms_before, result, rms_after = _fit(problem, options)
    flagged = []
    if screen:
        res = artefact_residual(problem)
        flagged = screen_spheres(res.fit_rms(problem.aux_values(res)), screen_factor, screen_floor)
        if flagged:
            log.warning("flagged %d sphere(s) with a mis-triggered hit: %s; re-identifying without them",
                        len(flagged), [(g, j) for g, j, _ in flagged])
            start = problem.params.values()
            problem = pcmm_problem(nominal, hits, artefact, use, sigma, {(g, j) for g, j, _ in flagged}, gauge_sigma)
            problem.params.set_values({n: start[n] for n in reduced_names()})
            _, _, result, rms_after = _fit(problem, options)
    geo = problem_geometry(problem)
    res = artefact_residual(problem)
    return PCMMCalibration(nominal, geo, geo.reduced_vector() - nominal.reduced_vector(), reduced_names(), result,
                           problem, res.kinematics(problem.aux_values(res)).poses, rms_before, rms_after, flagged,
                           msgs)


# ---- predicted uncertainty ----------------------------------------------------------------------
def machine_jacobian(geo: PCMMGeometry, hits: ProbeHits, artefact: Artefact, use: str = "both",
                     sigma: float = ROW_SIGMA) -> tuple[np.ndarray, np.ndarray]:
    """(J (M, 32), G (M, 4 N)): derivatives of the rows (scaled by 1/sigma) with respect to the reduced
    parameters and to the axis readings, for the machine `geo`."""
    problem = pcmm_problem(geo, hits, artefact, use, sigma)
    res = artefact_residual(problem)
    aux = problem.aux_values(res)
    J = problem.evaluate().J[:, reduced_columns(problem)]
    keep = np.tile(res.row_scale() != 0, res.n_terms)
    G = res.reading_jacobian(aux)[keep] * np.tile(res.row_scale()[res.row_scale() != 0], res.n_terms)[:, None]
    return J, G


def predicted_covariance(geo: PCMMGeometry, hits: ProbeHits, artefact: Artefact, sigma_axis: float,
                         use: str = "both", rank_rtol: float = 1e-8) -> np.ndarray:
    """(32, 32) covariance of the estimable part of d_eps for independent axis noise sigma_axis (m):
    J^+ (G sigma^2 G^T) J^+T with G = dE/d(readings) (first order; gauge directions have zero variance)."""
    J, G = machine_jacobian(geo, hits, artefact, use)
    A = np.linalg.pinv(J, rcond=rank_rtol) @ G
    return sigma_axis ** 2 * A @ A.T


def row_space_projector(J: np.ndarray, rtol: float = 1e-8) -> np.ndarray:
    """(32, 32) orthogonal projector onto the row space of J (what the data can see)."""
    _, s, Vt = np.linalg.svd(J, full_matrices=False)
    V = Vt[s > rtol * s[0]]
    return V.T @ V
