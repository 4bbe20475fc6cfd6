"""The default prior's strengths (one per scale family), chosen by the evidence of the linearised Gaussian model.

Model (docs/validation.md): about the registered nominal model the scaled residual is r ~ J d + e, with
e ~ N(0, s2 I) (s2: the measured noise, in units of the stated sigmas) and each robot parameter's error
d_j ~ N(0, (lam * scale_j)^2), scale_j its physical scale (robocal.estimation.physical_scale). The
registration parameters (base, measurement set-up, tool) get a flat prior: they are projected out. The
evidence p(r | lam, s2) is maximised over s2 for each lam of a fixed grid and the best lam kept. Where the
prior covers parameters of several scale families (lengths, angles, ...: PhysicalScales.family), each family
then gets its own lam, the evidence maximised jointly from that common one (family_strengths): the ratio of
the length scale to the angle scale is a guess for any robot, and the data can tell it.

Why the evidence (and not GCV or cross-validation): it needs one linearisation, no refit (cross-validation
over folds would cost a fit per fold and per strength); it estimates the noise level s2 at the same time,
which the identifiability classification then uses; and on a problem the data determine it returns a broad
prior (lam at the top of the grid), so it does not bias what the data already decide.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

STRENGTHS = np.logspace(-2, 1, 31)     # lam: prior sigma from 1/100 to 10 physical scales
RANK_TOL = 1e-10


@dataclass
class Evidence:
    strength: float            # lam: prior sigma = lam * physical scale (the best common one)
    noise2: float              # s2: measured noise variance in units of the stated sigma^2
    log_evidence: np.ndarray   # over STRENGTHS (each maximised over s2)
    stderr: np.ndarray         # data-only standard error of each scaled column, in physical scales (inf: none)
    by_family: dict = field(default_factory=dict)   # the strength of each scale family (all = strength if one)


def project_out(J_flat: np.ndarray, *arrays: np.ndarray) -> tuple[int, list[np.ndarray]]:
    """(rank of J_flat, arrays with the span of J_flat's columns removed)."""
    if J_flat.shape[1] == 0:
        return 0, list(arrays)
    Q, R, _ = scipy.linalg.qr(J_flat, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    rank = int(np.sum(d > RANK_TOL * max(d[0], 1e-300))) if len(d) else 0
    Q = Q[:, :rank]
    return rank, [a - Q @ (Q.T @ a) for a in arrays]


def neg_log_evidence(t: np.ndarray, d2: np.ndarray, z2: np.ndarray, rest: float, n_rest: int) -> np.ndarray:
    """-log evidence (without its 2 pi term) of each candidate (a row of d2, z2) over a (candidates, points) array
    of t = log s2, the noise variance's logarithm."""
    v = np.exp(t)[..., None] + d2[:, None, :]
    return 0.5 * (np.sum(z2[:, None, :] / v, axis=-1) + np.sum(np.log(v), axis=-1) + rest * np.exp(-t)
                  + n_rest * t)


def noise_slope_and_curvature(t: np.ndarray, d2: np.ndarray, z2: np.ndarray, rest: float, n_rest: int
                              ) -> tuple[np.ndarray, np.ndarray]:
    """d/dt and d2/dt2 of neg_log_evidence at one t per candidate (a = s2 / v, q = z2 / v)."""
    s2 = np.exp(t)
    a = s2[:, None] / (s2[:, None] + d2)
    q = z2 * a / s2[:, None]
    return (0.5 * (np.sum(a - q * a, axis=1) - rest / s2 + n_rest),
            0.5 * (np.sum(q * a * (2 * a - 1) + a - a * a, axis=1) + rest / s2))


def profiled_log_evidence(d2: np.ndarray, z2: np.ndarray, rest: float, n_rest: int,
                          scale0: float) -> tuple[np.ndarray, np.ndarray]:
    """For each candidate prior (a row of d2: the squared singular values of the prior-scaled columns; z2: the
    squared projections of the data on their left singular vectors), the log evidence maximised over the noise
    variance s2, and that s2. rest: the data's squared norm outside those singular vectors, over n_rest rows."""
    rest = rest if n_rest else 0.0
    # each candidate's best t: the best of a grid one e-fold apart over the bracket, then Newton's method kept
    # inside a bracket a step either side of it (bisection where a step leaves it), for every candidate at once
    grid = np.log(scale0) + np.arange(-30.0, 5.01, 1.0)
    t = grid[np.argmin(neg_log_evidence(np.broadcast_to(grid, (len(d2), len(grid))), d2, z2, rest, n_rest), axis=1)]
    lo, hi = np.maximum(t - 1.0, grid[0]), np.minimum(t + 1.0, grid[-1])
    for _ in range(100):
        g, h = noise_slope_and_curvature(t, d2, z2, rest, n_rest)
        lo, hi = np.where(g < 0, t, lo), np.where(g > 0, t, hi)    # the minimum lies where the slope turns +
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(h > 0, -g / h, np.nan)
        new = t + step
        new = np.where(np.isfinite(new) & (new >= lo) & (new <= hi), new, 0.5 * (lo + hi))   # t itself may be an end
        done = np.abs(new - t) < 1e-10
        t = new
        if np.all(done):
            break
    return -neg_log_evidence(t[:, None], d2, z2, rest, n_rest)[:, 0], np.exp(t)


@dataclass
class EvidenceBasis:
    """The data seen through the prior-scaled columns A (unit strength), the flat columns projected out:
    A = U diag(d) Vt, z = U^T y, and the data's squared norm outside U (rest, over n_rest rows); scale0 a typical
    noise variance (the mean square of y) that brackets the profiled one."""
    d: np.ndarray
    Vt: np.ndarray
    z: np.ndarray
    rest: float
    n_rest: int
    scale0: float


def evidence_basis(J: np.ndarray, r: np.ndarray, scales: np.ndarray, n_rows: int | None = None) -> EvidenceBasis:
    """The EvidenceBasis of the columns of J with a finite scale (each multiplied by it; the others flat).
    n_rows: the number of data rows when J and r are the triangle of [J r] (choose_strength)."""
    scaled = np.isfinite(scales)
    rank_flat, (y, A) = project_out(J[:, ~scaled], np.asarray(r, float), J[:, scaled] * scales[scaled])
    m_eff = (len(y) if n_rows is None else n_rows) - rank_flat
    U, d, Vt = np.linalg.svd(A, full_matrices=False)
    z = U.T @ y
    return EvidenceBasis(d, Vt, z, max(float(y @ y - z @ z), 0.0), max(m_eff - len(d), 0),
                         max(float(y @ y) / max(m_eff, 1), 1e-300))


def family_strengths(basis: EvidenceBasis, families: np.ndarray, start: float, strengths: np.ndarray, fixed=()
                     ) -> tuple[dict[str, float], float]:
    """One strength per scale family, maximising the evidence jointly: from the best common strength, each family
    in turn moves to its best grid value with the others held, until a sweep changes nothing (docs/validation.md,
    "One strength per scale family"). Returns ({family: strength}, the noise variance that goes with it).

    From the unit-strength columns' SVD A = U diag(d) Vt and z = U^T y (`basis`): per-column strengths L scale them to
    A L = U C with C = diag(d) Vt L, whose SVD C = P S Q^T gives the singular values S and the projections P^T z
    (computed as the eigenvectors of C C^T);
    the part of the data outside the columns' span (rest) does not depend on L. A family in `fixed` (columns
    already scaled by a prior the user gave) keeps strength 1."""
    strengths = np.asarray(strengths, float)
    order = list(dict.fromkeys(families))
    z, rest, n_rest, scale0 = basis.z, basis.rest, basis.n_rest, basis.scale0
    DV = basis.d[:, None] * basis.Vt
    # C C^T = sum over families of lam_f^2 B_f, B_f = D Vt_f Vt_f^T D: its eigenvalues are S^2 and its
    # eigenvectors P (a symmetric k x k problem per candidate, cheaper than the SVD of C)
    gram = {f: DV[:, families == f] @ DV[:, families == f].T for f in order}

    def evaluate(f: str) -> tuple[np.ndarray, np.ndarray]:
        held = sum(current[h] ** 2 * gram[h] for h in order if h != f)
        S2, P = np.linalg.eigh(held + strengths[:, None, None] ** 2 * gram[f])
        z2 = np.einsum("cki,k->ci", P, z) ** 2
        return profiled_log_evidence(np.clip(S2, 0.0, None), z2, rest, n_rest, scale0)

    current = {f: 1.0 if f in fixed else float(start) for f in order}
    noise2 = np.nan
    searched = {f: False for f in order}     # f's best is known given the others' current values
    for _ in range(20):
        moved = False
        for f in (f for f in order if f not in fixed):
            if searched[f]:
                continue                     # nothing else moved since f was searched: it would stay
            values, noise = evaluate(f)
            here = int(np.argmin(np.abs(np.log(strengths) - np.log(current[f]))))
            i = int(np.argmax(values))
            if values[here] >= values[i] - 1e-9:
                i = here                                           # a tie keeps the current value
            if i != here:
                moved = True
                searched = dict.fromkeys(order, False)
            searched[f] = True
            current[f], noise2 = float(strengths[i]), float(noise[i])
        if not moved:
            break
    return current, noise2


def choose_strength(J: np.ndarray, r: np.ndarray, scales: np.ndarray, strengths=STRENGTHS,
                    n_rows: int | None = None, families=None) -> Evidence:
    """Evidence-optimal prior strength for the columns of J with a finite scale (the others are flat).

    J (m, n): Jacobian of the scaled data rows; r (m,): scaled residual at the linearisation point. Or, with
    n_rows = m, the columns of the triangle T of [J r] (T^T T = [J r]^T [J r]): only inner products enter.
    families: each column's scale family (robocal.estimation.physical_scale.PhysicalScales.family); with two or
    more among the scaled columns, each family gets its own strength (`Evidence.by_family`).
    """
    scales = np.asarray(scales, float)
    scaled = np.isfinite(scales)
    basis = evidence_basis(J, r, scales, n_rows)
    d, Vt, z = basis.d, basis.Vt, basis.z
    k = len(d)
    lam = np.asarray(strengths, float)
    curve, noise = profiled_log_evidence((lam[:, None] * d) ** 2, np.broadcast_to(z ** 2, (len(lam), k)), basis.rest,
                                         basis.n_rest, basis.scale0)
    i = int(np.argmax(curve))
    fam = np.asarray(families if families is not None else ["common"] * len(scales), dtype=object)[scaled]
    by_family = {f: float(lam[i]) for f in dict.fromkeys(fam)}
    noise2 = float(noise[i])
    if len(by_family) > 1 and k:
        by_family, noise2 = family_strengths(basis, fam, lam[i], lam)
    stderr = np.full(len(scales), np.inf)
    big = d > RANK_TOL * (d[0] if k else 1.0)
    var = (Vt[big] ** 2 / d[big, None] ** 2).sum(0) * noise2 if k else np.zeros(0)
    if k and big.sum() == len(d):
        stderr[scaled] = np.sqrt(var)
    elif k:   # a singular scaled block: the null directions are not determined at all
        null = (Vt[~big] ** 2).sum(0) > 1e-12
        stderr[scaled] = np.where(null, np.inf, np.sqrt(var))
    return Evidence(float(lam[i]), noise2, np.array(curve), stderr, by_family)
