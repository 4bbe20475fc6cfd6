"""Self-calibration of the 4-PUU parallel CMM from a multi-sphere artefact (spec seed-003 §7-9).

The loop of the patent: substitute (FK of every hit with the current parameters, tip points, sphere
fits, distance and radius errors) -> identify (Levenberg-Marquardt step on the 32 reduced parameters
with the analytic Jacobian through the fit sensitivities) -> correct, until the parameters stop
changing. Every iteration is logged and kept in `PCMMCalibration.history`.

Gauge: the 32-column Jacobian has rank 27; the five blind directions (base x, y, z, base rotation z,
theta zero) are handled, never silently returned: gauge="svd" (default) takes minimum-norm steps in
the Marquardt-scaled row space, so no step ever moves along them; gauge="fix" fixes the five columns
that column-pivoted QR leaves out. The result reports the rank, singular values and null space.

Units: SI (m, rad). Rows: per placement, S(S-1)/2 distance errors then S radius errors, as in
robocal.residuals.sphere_artefact (whose `artefact_rows` this fast path shares).
"""
from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg

from robocal.errors import InputError
from robocal.systems.pcmm.machine import Artefact, ProbeHits
from robocal.systems.pcmm.kinematics import (N_REDUCED, PCMMGeometry, forward_kinematics, inverse_kinematics,
                                         pose_error_jacobian, reduced_names, rz, tip_error_jacobian,
                                         tip_points, tip_reading_jacobian)
from robocal.residuals.sphere_artefact import artefact_rows, pair_indices

log = logging.getLogger(__name__)
EXPECTED_RANK = 27     # 32 reduced parameters minus 5 gauge directions


class AcquisitionWarning(UserWarning):
    """The probing design cannot determine every identifiable parameter."""


@dataclass
class CalibrationOptions:
    use: str = "both"                 # "both", "distance" or "radius"
    weight_distance: float = 1.0
    weight_radius: float = 1.0
    gauge: str = "svd"                # "svd" (minimum-norm steps) or "fix" (QR-chosen columns fixed)
    rank_rtol: float = 1e-8           # singular values below rtol * largest count as zero
    xtol: float = 1e-11               # stop when |step| <= xtol (1 + |d_eps|)   (m and rad)
    ftol: float = 1e-14               # ... or the relative cost decrease of an accepted step is below
    gtol: float = 1e-12               # ... or the Gauss-Newton step would lower the cost by less than gtol
    max_iter: int = 50
    mu0: float = 1e-3                 # initial damping, relative to the largest scaled singular value^2
    mu_max: float = 1e8               # stop when the damping blows up past this (relative)
    screen: bool = False              # flag (and drop) spheres with a mis-triggered hit
    screen_factor: float = 5.0        # flag a sphere whose fit RMS exceeds factor * robust scale of all
    screen_floor: float = 1e-7        # ... and this floor (m), so that a noise-free fit flags nothing


@dataclass
class Evaluation:
    rows: np.ndarray         # (M,) weighted residuals E, m
    jacobian: np.ndarray     # (M, 32) dE/d(eps), or empty
    kind: np.ndarray         # (M,) "distance" / "radius"
    placement: np.ndarray    # (M,) placement index of each row
    spheres: list            # (M,) tuple of the spheres each row uses
    fit_rms: np.ndarray      # (G, S) RMS of each sphere fit, m
    reading_jacobian: np.ndarray | None = None   # (M, 4 N) dE/d(readings)
    poses: np.ndarray | None = None


@dataclass
class IterationRecord:
    iteration: int
    cost: float              # 0.5 |E|^2 after the iteration
    rms: float
    step_norm: float
    mu: float
    rank: int
    tries: int


@dataclass
class PCMMCalibration:
    nominal: PCMMGeometry
    geometry: PCMMGeometry               # identified
    d_eps: np.ndarray                    # (32,) identified - nominal, order of `names`
    names: list[str]
    history: list[IterationRecord]
    converged: bool
    message: str
    rank: int
    singular_values: np.ndarray          # of the unscaled J at the solution (SI)
    null_space: np.ndarray               # (32, 32 - rank) orthonormal
    covariance: np.ndarray               # s^2 (J^T J)^+ with s^2 = |E|^2 / (M - rank)
    rms_before: dict
    rms_after: dict
    flagged: list = field(default_factory=list)     # [(placement, sphere, fit RMS m)]
    warnings: list = field(default_factory=list)
    evaluation: Evaluation | None = None


# ---- substitute: residuals and Jacobian ---------------------------------------------------------
def evaluate(geo: PCMMGeometry, hits: ProbeHits, artefact: Artefact, options: CalibrationOptions | None = None,
             jacobian: bool = True, reading_jacobian: bool = False, y0=None) -> Evaluation:
    """Distance and radius errors of every placement for machine `geo` (and their Jacobians)."""
    opt = options or CalibrationOptions()
    if opt.use not in ("both", "distance", "radius"):
        raise InputError(f"use must be both, distance or radius, got '{opt.use}'", field="use")
    rho = np.asarray(hits.readings, dtype=float)
    if y0 is None:
        y0 = np.column_stack([np.broadcast_to(geo.home[:3], (len(rho), 3)), hits.theta_cmd])
    Y, _ = forward_kinematics(geo, rho, y0)
    X = tip_points(geo, Y)
    TJ = tip_error_jacobian(geo, Y, rho) if jacobian else None
    TR = tip_reading_jacobian(geo, Y, rho) if reading_jacobian else None
    S = artefact.n_spheres
    excluded = set(getattr(hits, "excluded", ()) or ())
    out_r, out_J, out_R, out_k, out_p, out_s, fit_rms = [], [], [], [], [], [], []
    for g, groups in enumerate(hits.groups()):
        if len(groups) != S:
            raise InputError(f"placement {g} probes {len(groups)} spheres, the artefact has {S}", field="sphere")
        present = [j for j in range(S) if (g, j) not in excluded]
        pairs = [(present[a], present[b]) for a, b in pair_indices(len(present))]
        keep = np.array([opt.use != "radius"] * len(pairs) + [opt.use != "distance"] * len(present), dtype=bool)
        w = np.array([opt.weight_distance] * len(pairs) + [opt.weight_radius] * len(present))[keep]
        kinds = np.array(["distance"] * len(pairs) + ["radius"] * len(present))[keep]
        used = [u for u, k in zip(pairs + [(j,) for j in present], keep) if k]
        pts = [X[groups[j]] for j in present]
        rows, dX, fits = artefact_rows(pts, artefact.distances[np.ix_(present, present)], artefact.radii[present],
                                       geo.tip_radius, source=f"placement {g}")
        idx = np.concatenate([groups[j] for j in present])
        out_r.append(w * rows[keep])
        if jacobian:
            out_J.append(w[:, None] * (dX[keep] @ TJ[idx].reshape(-1, N_REDUCED)))
        if reading_jacobian:
            R = np.zeros((int(keep.sum()), 4 * len(rho)))
            dXk = np.einsum("rna,nab->rnb", dX[keep].reshape(-1, len(idx), 3), TR[idx])   # (rows, hits, 4)
            for n, i in enumerate(idx):
                R[:, 4 * i:4 * i + 4] = w[:, None] * dXk[:, n]
            out_R.append(R)
        out_k.append(kinds)
        out_p.append(np.full(len(kinds), g))
        out_s += used
        rms_g = np.full(S, np.nan)
        rms_g[present] = [f.rms for f in fits]
        fit_rms.append(rms_g)
    return Evaluation(np.concatenate(out_r), np.vstack(out_J) if jacobian else np.zeros((0, N_REDUCED)),
                      np.concatenate(out_k), np.concatenate(out_p), out_s, np.array(fit_rms),
                      np.vstack(out_R) if reading_jacobian else None, Y)


def rms_by_kind(ev: Evaluation) -> dict:
    out = {"all": float(np.sqrt(np.mean(ev.rows ** 2)))}
    for k in ("distance", "radius"):
        sel = ev.kind == k
        if sel.any():
            out[k] = float(np.sqrt(np.mean(ev.rows[sel] ** 2)))
    return out


# ---- identifiability and acquisition warnings ------------------------------------------------
@dataclass
class Identifiability:
    singular_values: np.ndarray   # of J as given (SI), largest first, padded to 32
    rank: int                     # exact numerical rank: s > rtol s_max (the gauge is exact, ~1e-16)
    null_space: np.ndarray        # (32, 32 - rank)
    smallest_kept: float
    condition: float              # largest / smallest kept singular value
    effective_rank: int           # column-scaled singular values above weak_rtol * largest
    scaled_singular_values: np.ndarray


def identifiability(J: np.ndarray, rtol: float = 1e-8, weak_rtol: float = 1e-3) -> Identifiability:
    """Singular values, rank, null space and condition of J; plus an effective rank on the unit-column
    scaled J (unit-independent) that also counts directions too weak to be useful as missing.

    weak_rtol = 1e-3 is a heuristic from the reference design: with theta varied by +-0.3 rad the 27th
    scaled singular value is ~2e-3 of the largest, with theta fixed the 18th falls to ~5e-4 (spec §6)."""
    _, s, Vt = np.linalg.svd(J, full_matrices=True)
    s_full = np.zeros(J.shape[1])
    s_full[:len(s)] = s
    rank = int(np.sum(s_full > rtol * s_full[0])) if s_full[0] > 0 else 0
    kept = s_full[rank - 1] if rank else 0.0
    norms = np.linalg.norm(J, axis=0)
    ss = np.zeros(J.shape[1])
    sv = np.linalg.svd(J / np.where(norms > 0, norms, 1.0), compute_uv=False)
    ss[:len(sv)] = sv
    eff = int(np.sum(ss > weak_rtol * ss[0])) if ss[0] > 0 else 0
    return Identifiability(s_full, rank, Vt[rank:].T, float(kept), float(s_full[0] / kept) if kept else np.inf,
                           eff, ss)


def check_acquisition(geo: PCMMGeometry, hits: ProbeHits, artefact: Artefact,
                      options: CalibrationOptions | None = None) -> list[str]:
    """Warnings about the probing design (issued as AcquisitionWarning and returned as text)."""
    opt = options or CalibrationOptions()
    ev = evaluate(geo, hits, artefact, opt)
    ident = identifiability(ev.jacobian, opt.rank_rtol)
    msgs = []
    M = len(ev.rows)
    if M < EXPECTED_RANK:
        msgs.append(f"too few equations: {M} distance/radius rows for {EXPECTED_RANK} identifiable parameters "
                    f"({N_REDUCED} minus 5 gauge directions); probe more artefact placements")
    if ident.effective_rank < EXPECTED_RANK:
        theta = ev.poses[:, 3]
        spread = float(np.ptp(theta))
        cause = ""
        if spread < 0.05:
            cause = (f" The platform rotation was not varied while probing (theta spread {spread:.3g} rad): "
                     "vary theta from hit to hit (e.g. +-0.3 rad) to observe the platform joints.")
        msgs.append(f"the design determines only {ident.effective_rank} of the {EXPECTED_RANK} identifiable "
                    f"parameter combinations (effective rank of the column-scaled Jacobian; exact rank "
                    f"{ident.rank} of {N_REDUCED}).{cause}")
    for m in msgs:
        log.warning(m)
        warnings.warn(m, AcquisitionWarning, stacklevel=2)
    return msgs


# ---- identify, correct, substitute --------------------------------------------------------------
def _solve_lm(nominal, x0, hits, artefact, opt, history, y0):
    """LM on the reduced vector from x0; returns x, converged, message, last evaluation, poses."""
    x = x0.copy()
    xn = nominal.reduced_vector()
    ev = evaluate(nominal.with_reduced(x), hits, artefact, opt, y0=y0)
    cost = 0.5 * float(ev.rows @ ev.rows)
    scale = np.linalg.norm(ev.jacobian, axis=0)
    scale[scale == 0] = 1.0
    mu = None
    if opt.gauge == "fix":     # chosen once, at the start: the same five parameters stay fixed throughout
        cols = _qr_columns(ev.jacobian / scale, opt.rank_rtol)
    elif opt.gauge == "svd":
        cols = np.arange(N_REDUCED)
    else:
        raise InputError(f"gauge must be 'svd' or 'fix', got '{opt.gauge}'", field="gauge")
    for it in range(1, opt.max_iter + 1):
        Js = ev.jacobian / scale
        U, s, Vt = np.linalg.svd(Js[:, cols], full_matrices=False)
        k = int(np.sum(s > opt.rank_rtol * s[0]))
        U, s, Vt = U[:, :k], s[:k], Vt[:k]
        g = U.T @ ev.rows
        if 0.5 * float(g @ g) <= opt.gtol * cost:   # even the Gauss-Newton step cannot lower the cost
            history.append(IterationRecord(it, cost, float(np.sqrt(2 * cost / len(ev.rows))), 0.0,
                                           mu if mu is not None else 0.0, k, 0))
            return x, True, "cost at its minimum (Gauss-Newton decrease below gtol)", ev
        if mu is None:
            mu = opt.mu0 * s[0] ** 2
        tries = 0
        while True:
            tries += 1
            step = np.zeros(N_REDUCED)
            step[cols] = -(Vt.T @ (s / (s ** 2 + mu) * g)) / scale[cols]
            try:
                ev_try = evaluate(nominal.with_reduced(x + step), hits, artefact, opt, y0=ev.poses)
                cost_try = 0.5 * float(ev_try.rows @ ev_try.rows)
            except Exception as exc:   # FK left the workspace: treat as a rejected step
                log.debug("step rejected: %s", exc)
                cost_try = np.inf
            if cost_try < cost:
                mu /= 10.0
                break
            mu *= 10.0
            if mu > opt.mu_max * s[0] ** 2:
                history.append(IterationRecord(it, cost, np.sqrt(2 * cost / len(ev.rows)), 0.0, mu, k, tries))
                log.info("iteration %d: damping blew up (mu %.3g); stopping", it, mu)
                return x, False, "damping exceeded mu_max: no step reduces the cost", ev
        rel = (cost - cost_try) / max(cost, 1e-300)
        x, ev, cost = x + step, ev_try, cost_try
        snorm = float(np.linalg.norm(step))
        rec = IterationRecord(it, cost, float(np.sqrt(2 * cost / len(ev.rows))), snorm, mu, k, tries)
        history.append(rec)
        log.info("iteration %d: cost %.6g, rms %.6g m, |d eps| %.3g, mu %.3g, rank %d", it, rec.cost, rec.rms,
                 snorm, mu, k)
        if snorm <= opt.xtol * (1.0 + np.linalg.norm(x - xn)):
            return x, True, "parameters stopped changing (step below xtol)", ev
        if rel < opt.ftol:
            return x, True, "cost stopped decreasing (relative change below ftol)", ev
    return x, False, f"no convergence in {opt.max_iter} iterations", ev


def _qr_columns(Js: np.ndarray, rtol: float) -> np.ndarray:
    """Columns kept by column-pivoted QR (the others are fixed: the gauge)."""
    _, R, piv = scipy.linalg.qr(Js, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    k = int(np.sum(d > rtol * d[0]))
    return np.sort(piv[:k])


def screen_spheres(ev: Evaluation, factor: float, floor: float) -> list[tuple[int, int, float]]:
    """Spheres whose fit RMS stands out: (placement, sphere, RMS m) above max(factor * robust scale, floor)."""
    rms = np.nan_to_num(ev.fit_rms, nan=0.0)
    scale = 1.4826 * np.median(ev.fit_rms[np.isfinite(ev.fit_rms)])
    limit = max(factor * scale, floor)
    return [(int(g), int(j), float(rms[g, j])) for g, j in np.argwhere(rms > limit)]


def calibrate_pcmm(nominal: PCMMGeometry, hits: ProbeHits, artefact: Artefact,
                   options: CalibrationOptions | None = None) -> PCMMCalibration:
    """Identify the 32 reduced parameters from probe hits on the artefact, starting from `nominal`."""
    opt = options or CalibrationOptions()
    msgs = check_acquisition(nominal, hits, artefact, opt)
    history: list[IterationRecord] = []
    ev0 = evaluate(nominal, hits, artefact, opt, jacobian=False)
    rms_before = rms_by_kind(ev0)
    x, converged, message, ev = _solve_lm(nominal, nominal.reduced_vector(), hits, artefact, opt, history,
                                          ev0.poses)
    flagged = []
    if opt.screen:
        flagged = screen_spheres(ev, opt.screen_factor, opt.screen_floor)
        if flagged:
            log.warning("flagged %d sphere(s) with a mis-triggered hit: %s; re-identifying without them",
                        len(flagged), [(g, j) for g, j, _ in flagged])
            hits = replace(hits, excluded=frozenset(hits.excluded) | {(g, j) for g, j, _ in flagged})
            x, converged, message, ev = _solve_lm(nominal, x, hits, artefact, opt, history, None)
            message += f"; {len(flagged)} sphere(s) flagged and dropped"
    geo = nominal.with_reduced(x)
    ident = identifiability(ev.jacobian, opt.rank_rtol)
    dof = max(len(ev.rows) - ident.rank, 1)
    s2 = float(ev.rows @ ev.rows) / dof
    cov = s2 * np.linalg.pinv(ev.jacobian.T @ ev.jacobian, rcond=opt.rank_rtol ** 2, hermitian=True)
    return PCMMCalibration(nominal, geo, x - nominal.reduced_vector(), reduced_names(), history, converged,
                           message, ident.rank, ident.singular_values, ident.null_space, cov, rms_before,
                           rms_by_kind(ev), flagged, msgs, ev)


# ---- predicted uncertainty ----------------------------------------------------------------------
def predicted_covariance(geo: PCMMGeometry, hits: ProbeHits, artefact: Artefact, sigma_axis: float,
                         options: CalibrationOptions | None = None) -> np.ndarray:
    """(32, 32) covariance of the estimable part of d_eps for independent axis noise sigma_axis (m):
    J^+ (G sigma^2 G^T) J^+T with G = dE/d(readings) (first order; gauge directions have zero variance)."""
    opt = options or CalibrationOptions()
    ev = evaluate(geo, hits, artefact, opt, reading_jacobian=True)
    Jp = np.linalg.pinv(ev.jacobian, rcond=opt.rank_rtol)
    A = Jp @ ev.reading_jacobian
    return sigma_axis ** 2 * A @ A.T


def row_space_projector(J: np.ndarray, rtol: float = 1e-8) -> np.ndarray:
    """(32, 32) orthogonal projector onto the row space of J (what the data can see)."""
    _, s, Vt = np.linalg.svd(J, full_matrices=False)
    V = Vt[s > rtol * s[0]]
    return V.T @ V


# ---- compensation ------------------------------------------------------------------------------
def compensate_measurement(geo: PCMMGeometry, readings, theta_guess=None) -> np.ndarray:
    """Corrected tip coordinates (N, 3) from axis readings (N, 4): FK with the identified machine."""
    rho = np.asarray(readings, dtype=float).reshape(-1, 4)
    y0 = None if theta_guess is None else np.column_stack(
        [np.broadcast_to(geo.home[:3], (len(rho), 3)), np.asarray(theta_guess, dtype=float).reshape(-1)])
    return tip_points(geo, forward_kinematics(geo, rho, y0)[0])


def compensate_command(geo: PCMMGeometry, target_poses) -> np.ndarray:
    """Axis commands (N, 4) that bring the identified machine to the target poses (N, 4): exact IK."""
    return inverse_kinematics(geo, target_poses)


def tip_target_poses(geo: PCMMGeometry, tips, theta) -> np.ndarray:
    """Platform poses (N, 4) that put the tip centre at `tips` (N, 3) with rotation theta (N,)."""
    theta = np.asarray(theta, dtype=float).reshape(-1)
    q = np.asarray(tips, dtype=float).reshape(-1, 3) - np.einsum("nab,b->na", rz(theta), geo.stylus)
    return np.column_stack([q, theta])


def first_order_pose_correction(nominal: PCMMGeometry, d_eps, poses, readings) -> np.ndarray:
    """(N, 4) pose correction J_p d_eps at the nominal FK poses (spec §9, measurement mode)."""
    return np.einsum("nak,k->na", pose_error_jacobian(nominal, poses, readings), np.asarray(d_eps, dtype=float))


# ---- evaluation up to the gauge -------------------------------------------------------------------
def gauge_align(points, reference) -> tuple[np.ndarray, np.ndarray, float]:
    """Rigid transform (R, t) minimising |R p + t - ref| (Kabsch) and the aligned RMS (m)."""
    P, Q = np.asarray(points, dtype=float), np.asarray(reference, dtype=float)
    pc, qc = P.mean(axis=0), Q.mean(axis=0)
    U, _, Vt = np.linalg.svd((P - pc).T @ (Q - qc))
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    t = qc - R @ pc
    rms = float(np.sqrt(np.mean(np.sum((P @ R.T + t - Q) ** 2, axis=1))))
    return R, t, rms


@dataclass
class Validation:
    tip_rms: float        # rigid-aligned tip RMS, m
    tip_max: float
    pair_rms: float       # error of all pairwise tip distances, m
    pair_max: float


def validate(true_machine, model: PCMMGeometry, poses, true_ik=None) -> Validation:
    """Measure poses with the true machine, read them back with `model`: aligned tip and distance errors."""
    ik = true_ik or inverse_kinematics
    rho = ik(true_machine, poses)
    X_true = tip_points(true_machine, poses)
    X = compensate_measurement(model, rho, np.asarray(poses)[:, 3])
    R, t, rms = gauge_align(X, X_true)
    err = np.linalg.norm(X @ R.T + t - X_true, axis=1)
    iu = np.triu_indices(len(X), 1)
    dd = (np.linalg.norm(X[:, None] - X[None], axis=2) - np.linalg.norm(X_true[:, None] - X_true[None], axis=2))[iu]
    return Validation(rms, float(err.max()), float(np.sqrt(np.mean(dd ** 2))), float(np.abs(dd).max()))
