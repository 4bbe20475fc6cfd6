"""Information criteria of an identification Jacobian, and their fast evaluation for pose exchanges.

All criteria are to be MAXIMISED. They are functions of the information matrix M = J^T J of the
column-scaled, unit-variance Jacobian J (m rows, L identifiable columns), with singular values
sigma_1 >= ... >= sigma_L of J (sigma_i^2 = eigenvalues of M):

  D   log det M                                 D-optimal (volume of the confidence ellipsoid)
  E   sigma_L                                   E-optimal (worst-determined direction)
  A   -trace(M^-1)                              A-optimal (sum of the parameter variances)
  I   -trace(M^-1 W)                            I-optimal (average prediction variance, W given)
  O1  (sigma_1 ... sigma_L)^(1/L) / sqrt(m)     Borm & Menq (1991)
  O2  sigma_L / sigma_1                         Driels & Pathre (1990), inverse condition number
  O3  sigma_L                                   Nahvi, Hollerbach & Hayward (1994); same ranking as E
  O4  sigma_L^2 / sigma_1                       Nahvi & Hollerbach (1996), noise amplification index
  O5  1 / (1/sigma_1 + ... + 1/sigma_L)         Sun & Hollerbach (2008), A-optimality-like

D, A, I and O1 (a function of det M and m) are evaluated for many candidate changes at once with block
(Woodbury) updates of M^-1. The other singular-value criteria need the eigenvalues of each changed matrix;
`best_addition` avoids most of them with upper bounds (Rayleigh quotients, Rayleigh-Ritz, and Schur's
majorization of the diagonal by the eigenvalues for O5) and computes eigenvalues only for candidates whose
bound can still win.
"""
from __future__ import annotations

import numpy as np

CRITERIA = ("D", "E", "A", "I", "O1", "O2", "O3", "O4", "O5")
#: criteria that only depend on the eigenvalues of M (and on m for O1)
SPECTRAL = ("E", "O1", "O2", "O3", "O4", "O5")


def from_eigenvalues(criterion: str, lam: np.ndarray, m: np.ndarray | float) -> np.ndarray:
    """Criterion value from eigenvalues of M (last axis, any order); m = number of rows (for O1).

    A singular M gives -inf for D and A and 0 for the ratio criteria (nothing is determined).
    """
    lam = np.sort(np.maximum(np.asarray(lam, dtype=float), 0.0), axis=-1)
    sig = np.sqrt(lam)
    smin, smax = sig[..., 0], sig[..., -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        if criterion == "D":
            return np.sum(np.log(lam), axis=-1)
        if criterion == "A":
            return -np.sum(1.0 / lam, axis=-1)
        if criterion in ("E", "O3"):
            return smin
        if criterion == "O1":
            return np.exp(np.mean(np.log(sig), axis=-1)) / np.sqrt(m)
        if criterion == "O2":
            return np.where(smax > 0, smin / smax, 0.0)
        if criterion == "O4":
            return np.where(smax > 0, smin ** 2 / smax, 0.0)
        if criterion == "O5":
            return np.where(smin > 0, 1.0 / np.sum(1.0 / sig, axis=-1), 0.0)
    raise ValueError(f"unknown criterion '{criterion}' (known: {', '.join(CRITERIA)})")


def evaluate(criterion: str, M: np.ndarray, m: int, W: np.ndarray | None = None) -> float:
    """Criterion of one information matrix M (L x L) built from m rows."""
    if criterion == "I":
        try:
            return float(-np.trace(np.linalg.solve(M, W)))
        except np.linalg.LinAlgError:
            return -np.inf
    return float(from_eigenvalues(criterion, np.linalg.eigvalsh(M), m))


def all_criteria(M: np.ndarray, m: int, W: np.ndarray | None = None) -> dict[str, float]:
    """Every criterion of M (I only when W is given)."""
    out = {c: evaluate(c, M, m) for c in CRITERIA if c != "I"}
    if W is not None:
        out["I"] = evaluate("I", M, m, W)
    return out


def scores_after_adding(criterion: str, M: np.ndarray, m: int, B: np.ndarray, rows: np.ndarray,
                        W: np.ndarray | None = None) -> np.ndarray:
    """Criterion of M + B_k^T B_k for every candidate block k.

    M (L, L) must be positive definite (regularised by the caller); B (K, d, L) zero-padded blocks;
    rows (K,) true row count of each block (for O1's m).
    """
    if criterion in ("D", "A", "I", "O1"):
        L = np.linalg.cholesky(M)
        Minv = np.linalg.inv(L).T @ np.linalg.inv(L)          # M^-1 from its Cholesky factor
        P = (B.reshape(-1, B.shape[2]) @ Minv).reshape(B.shape)   # (K, d, L): one GEMM, not K small ones
        S = np.eye(B.shape[1]) + P @ B.transpose(0, 2, 1)      # I + B M^-1 B^T, (K, d, d); matmul: 4x einsum's speed
        logdet = 2.0 * np.sum(np.log(np.diag(L))) + np.linalg.slogdet(S)[1]
        if criterion == "D":
            return logdet
        if criterion == "O1":     # (prod sigma)^(1/L) / sqrt(m) = exp(log det M / (2 L)) / sqrt(m)
            return np.exp(logdet / (2 * M.shape[0])) / np.sqrt(m + rows)
        # Woodbury: (M + B^T B)^-1 = M^-1 - P^T S^-1 P, so tr((.)^-1 W) = tr(M^-1 W) - tr(S^-1 P W P^T)
        Wm = np.eye(M.shape[0]) if criterion == "A" else W
        H = (P @ Wm) @ P.transpose(0, 2, 1)
        return -(np.trace(Minv @ Wm) - np.trace(np.linalg.solve(S, H), axis1=1, axis2=2))
    lam = np.linalg.eigvalsh(M[None] + np.einsum("kdi,kdj->kij", B, B))
    return from_eigenvalues(criterion, lam, m + rows)


#: bounds are inflated by this relative amount so that rounding never prunes the true best candidate
BOUND_SLACK = 1e-9
#: candidates whose exact eigenvalues are computed together (one batched eigvalsh)
CHUNK = 16
#: weakest and strongest directions of M kept in the Rayleigh-Ritz bounds
RITZ_DIRECTIONS = 6
#: weakest directions of M whose block is solved exactly in the O5 pinching bound (half of a 30-column UR5 fit)
O5_BLOCK = 15


def _diagonal_bounds(criterion, lam, C):
    """Cheap upper bound of the criterion of M' = M + B_k^T B_k for every k, from the diagonal of M' in
    M's eigenbasis, diag_i = lam_i + |C e_i|^2 (C = B V), O(K d L):
      lambda_min(M') <= min_i diag_i and lambda_max(M') >= max_i diag_i   (Rayleigh quotients), tightened by the
          2 x 2 compressions of M' on the two weakest and the two strongest directions (Rayleigh-Ritz);
      O5: the diagonal of a symmetric matrix is majorized by its eigenvalues (Schur), so for the convex
          f(x) = x^-1/2, sum_i f(diag_i) <= sum_i f(lambda_i(M')) = 1 / O5(M').
    """
    diag = lam + np.einsum("kdi,kdi->ki", C, C)
    if criterion == "O5":
        with np.errstate(divide="ignore"):
            return 1.0 / np.sum(1.0 / np.sqrt(np.maximum(diag, 0.0)), axis=1)
    low, high = diag.min(axis=1), diag.max(axis=1)
    if len(lam) >= 2:
        # the 2 x 2 compressions on the two weakest and the two strongest directions, in closed form
        for i, j, sign in ((0, 1, -1.0), (-2, -1, 1.0)):
            mean, half = 0.5 * (diag[:, i] + diag[:, j]), 0.5 * (diag[:, i] - diag[:, j])
            off = np.einsum("kd,kd->k", C[:, :, i], C[:, :, j])
            extreme = mean + sign * np.sqrt(half * half + off * off)
            low, high = (np.minimum(low, extreme), high) if sign < 0 else (low, np.maximum(high, extreme))
    return _bound_from_extremes(criterion, low, high)


def _bound_from_extremes(criterion, low, high):
    """Upper bound of E, O2, O3 or O4 from low >= lambda_min(M') and high <= lambda_max(M')."""
    low = np.maximum(low, 0.0)
    if criterion in ("E", "O3"):
        return np.sqrt(low)
    if criterion == "O2":
        return np.sqrt(low / high)
    return low / np.sqrt(high)                      # O4


def _ritz_bounds(criterion, lam, C):
    """Tighter upper bound for a few candidates, (K, d, L) C = B V, from compressions of M' onto the r weakest
    and r strongest directions of M:
      E, O2, O3, O4 (Rayleigh-Ritz): lambda_min(M') <= lambda_min(diag(lam_r) + C_r^T C_r), and
          lambda_max(M') >= lambda_max of the same on the strongest r;
      O5: the eigenvalues of the block-diagonal part of M' (weakest O5_BLOCK directions, the rest) are majorized
          by those of M' (pinching), and the rest's diagonal by its eigenvalues, as in `_diagonal_bounds`.
    """
    if criterion == "O5":
        r = min(len(lam), O5_BLOCK)
        weak = C[:, :, :r]
        inner = np.maximum(np.linalg.eigvalsh(np.diag(lam[:r]) + weak.transpose(0, 2, 1) @ weak), 0.0)
        rest = lam[r:] + np.einsum("kdi,kdi->ki", C[:, :, r:], C[:, :, r:])
        with np.errstate(divide="ignore"):
            return 1.0 / (np.sum(1.0 / np.sqrt(inner), axis=1) + np.sum(1.0 / np.sqrt(rest), axis=1))
    r = min(len(lam), RITZ_DIRECTIONS)
    weak, strong = C[:, :, :r], C[:, :, -r:]
    low = np.linalg.eigvalsh(np.diag(lam[:r]) + weak.transpose(0, 2, 1) @ weak)[:, 0]
    high = np.linalg.eigvalsh(np.diag(lam[-r:]) + strong.transpose(0, 2, 1) @ strong)[:, -1]
    return _bound_from_extremes(criterion, low, high)


def best_addition(criterion: str, M: np.ndarray, m: int, B: np.ndarray, rows: np.ndarray,
                  W: np.ndarray | None = None) -> tuple[int, float]:
    """(k, value) of the candidate block that maximises the criterion of M + B_k^T B_k.

    Ties go to the lowest k, as with argmax over `scores_after_adding`, of which this is a faster
    equivalent for the eigenvalue criteria: every candidate gets a cheap upper bound (`_diagonal_bounds`);
    in order of decreasing bound, chunks get the tighter `_ritz_bounds` and the exact
    eigenvalues only where the bound can still beat the best value found; the search stops at the first
    chunk whose bounds cannot. The exact values are those of `scores_after_adding`, so the choice is too.
    """
    if criterion not in ("E", "O2", "O3", "O4", "O5"):
        s = scores_after_adding(criterion, M, m, B, rows, W)
        k = int(np.argmax(s))
        return k, float(s[k])
    lam, V = np.linalg.eigh(M)
    lam = np.maximum(lam, 0.0)
    C = B @ V                                                       # (K, d, L): blocks in M's eigenbasis
    ub = _diagonal_bounds(criterion, lam, C) * (1 + BOUND_SLACK) + 1e-300
    order = np.argsort(-ub, kind="stable")
    best_k, best = -1, -np.inf
    for start in range(0, len(order), CHUNK):
        idx = order[start:start + CHUNK]
        if ub[idx[0]] < best:
            break
        idx = idx[ub[idx] >= best]
        if len(idx):
            idx = idx[_ritz_bounds(criterion, lam, C[idx]) * (1 + BOUND_SLACK) + 1e-300 >= best]
        if not len(idx):
            continue
        s = scores_after_adding(criterion, M, m, B[idx], rows[idx], W)
        for k, v in zip(idx, s):
            if v > best or (v == best and k < best_k):
                best_k, best = int(k), float(v)
    return best_k, best
