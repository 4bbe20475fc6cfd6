"""Which parameters the data can determine, and how well.

Base-parameter selection walks the parameters in their declared order and keeps each one whose
unit-scaled Jacobian column stands out of the span of the columns already kept by more than `rtol`
(its remaining norm: 1 = orthogonal to everything kept, 0 = a combination of it). The result depends
only on the order and on the column geometry, never on floating-point ties, so the same data give
the same set on every machine (a final singular-value test drops, while the kept block's condition
exceeds 1/rtol, the latest parameter taking part in its weakest direction); and it is predictable: robocal's presets put the measurement frame
first, then the joints from root to tip, then frames on the robot, so a later parameter is the one
dropped when two cannot be told apart (a revolute joint's offset is kept, its placement's rotation
about the same axis dropped). The condition number of the kept block is reported alongside.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.linalg.lapack

NEGLIGIBLE = 1e-12
PARTICIPATES = 0.1  # share of the weakest singular vector that makes a parameter part of a dependency


@dataclass
class BaseSelection:
    """Result of `select_base_parameters`.

    independent  column indices kept, in parameter order
    dependent    column indices that the data cannot separate from the kept ones
    regrouping   (len(independent), len(dependent)) with J[:, dependent] ~= J[:, independent] @ regrouping
    condition    condition number of the column-scaled kept block
    singular_values  of the whole column-scaled matrix (largest first), computed on first use from
                 `geometry` (that matrix, or its n x n triangle): most selections never need them
    """

    names: list[str]
    independent: list[int]
    dependent: list[int]
    regrouping: np.ndarray
    condition: float
    geometry: np.ndarray
    rtol: float
    _singular: np.ndarray | None = field(default=None, repr=False)

    @property
    def singular_values(self) -> np.ndarray:
        if self._singular is None:
            W = self.geometry
            self._singular = np.linalg.svd(W, compute_uv=False) if W.shape[1] else np.zeros(0)
        return self._singular

    @property
    def no_effect(self) -> list[int]:
        """Dependent columns that have no effect at all on the measurements."""
        return [j for k, j in enumerate(self.dependent) if not np.any(self.regrouping[:, k])]

    @property
    def rank(self) -> int:
        return len(self.independent)

    def confounded_with(self, dependent_index: int, threshold: float = 1e-6) -> list[tuple[str, float]]:
        """(name, coefficient) of kept parameters that a dropped one is a combination of."""
        k = self.dependent.index(dependent_index)
        coef = self.regrouping[:, k]
        scale = np.max(np.abs(coef)) if coef.size else 0.0
        if not scale > 0:
            return []
        keep = np.flatnonzero(np.abs(coef) > threshold * max(scale, 1.0))
        out = [(self.names[self.independent[i]], c) for i, c in zip(keep.tolist(), coef[keep].tolist())]
        return sorted(out, key=lambda t: -abs(t[1]))

    def keep_also(self, indices) -> "BaseSelection":
        """The same selection with some dependent columns kept anyway (parameters with priors)."""
        extra = [j for j in self.dependent if j in set(indices)]
        if not extra:
            return self
        independent = sorted(self.independent + extra)
        dependent = [j for j in self.dependent if j not in extra]
        rows = {j: k for k, j in enumerate(self.independent)}
        regroup = np.zeros((len(independent), len(dependent)))
        for k_new, j in enumerate(independent):
            if j in rows:
                regroup[k_new] = self.regrouping[rows[j], [self.dependent.index(d) for d in dependent]]
        return BaseSelection(self.names, independent, dependent, regroup, self.condition, self.geometry,
                             self.rtol)

    def describe(self) -> list[str]:
        """One sentence per dropped parameter, naming what it is confounded with."""
        lines = []
        for j in self.dependent:
            partners = self.confounded_with(j)
            if not partners:
                lines.append(f"{self.names[j]} has no effect on these measurements")
            else:
                terms = ", ".join(f"{n} ({c:+.3g})" for n, c in partners[:6])
                more = f" and {len(partners) - 6} more" if len(partners) > 6 else ""
                lines.append(f"{self.names[j]} cannot be separated from {terms}{more}")
        return lines


def select_base_parameters(J: np.ndarray, names: list[str] | None = None, rtol: float = 1e-8,
                           allowed: set[int] | None = None) -> BaseSelection:
    """Choose a maximal set of columns of J that the data determine (see module doc).

    J: (m, n) Jacobian of the (weighted) residuals; names: n parameter names; allowed: column indices
    that may be kept (default all; the others are reported as dependent).
    """
    J = np.asarray(J, dtype=float)
    m, n = J.shape
    names = list(names) if names is not None else [f"p{i}" for i in range(n)]
    norms = np.linalg.norm(J, axis=0)
    # A column this small next to the largest is rounding noise (a point on a joint's own axis, say):
    # normalising it would turn the noise into a spurious independent direction.
    live = norms > NEGLIGIBLE * (norms.max() if n else 0.0)
    scaled = np.zeros_like(J)
    scaled[:, live] = J[:, live] / norms[live]
    # Same column geometry in an n x n matrix: R^T R = J^T J.
    W = scipy.linalg.qr(scaled, mode="r")[0][:n] if m > n else scaled.copy()
    if n and m >= n and live.all() and (allowed is None or set(range(n)) <= set(allowed)):
        # full rank with room to spare: every column's remaining norm is at least sigma_min, and sigma_max is at
        # least 1 (unit columns), so the walk below would keep them all and the singular-value test pass
        sv = np.linalg.svd(W, compute_uv=False)
        if sv[-1] > 2.0 * rtol * sv[0]:
            return BaseSelection(names, list(range(n)), [], np.zeros((n, 0)), float(sv[0] / sv[-1]), W, rtol, sv)
    chosen: list[int] = []
    basis = np.zeros((W.shape[0], n))   # orthonormal columns 0..k-1 span the chosen columns
    for j in range(n):
        if not live[j] or (allowed is not None and j not in allowed):
            continue
        qv = W[:, j].copy()
        B = basis[:, :len(chosen)]
        for _ in range(2):  # Gram-Schmidt twice: orthogonal to working precision
            qv -= B @ (B.T @ qv)
        remaining_norm = math.sqrt(qv @ qv)     # np.linalg.norm's own formula, without its overhead
        if remaining_norm > rtol:
            basis[:, len(chosen)] = qv / remaining_norm
            chosen.append(j)
    # Remaining norms are not rank-revealing when a dependency is spread thinly over several columns, so
    # the kept block must also pass a singular-value test: while its condition exceeds 1/rtol, drop the
    # latest parameter that takes part in the weakest direction.
    sv = np.zeros(0)      # singular values of the kept block (its condition below)
    while chosen:
        sv = np.linalg.svd(W[:, chosen], compute_uv=False)
        if sv[-1] > rtol * sv[0]:
            break
        _, _, Vt = np.linalg.svd(W[:, chosen], full_matrices=False)
        v = np.abs(Vt[-1])
        chosen.pop(max(k for k in range(len(chosen)) if v[k] > PARTICIPATES * v.max()))
        sv = np.zeros(0)
    independent = sorted(chosen)
    dependent = sorted(set(range(n)) - set(chosen))
    if independent and dependent:
        beta = np.linalg.lstsq(W[:, independent], W[:, dependent], rcond=None)[0]
        s_in = np.where(live[independent], norms[independent], 1.0)
        regroup = beta / s_in[:, None] * norms[dependent][None, :]
    else:
        regroup = np.zeros((len(independent), len(dependent)))
    if independent:       # chosen is in increasing order: W[:, independent] is the block tested last
        condition = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    else:
        condition = float("inf")
    return BaseSelection(names, independent, dependent, regroup, condition, W, rtol)


def covariance(J: np.ndarray, sigma2: float = 1.0) -> np.ndarray:
    """sigma2 * (J^T J)^-1 by QR of J (no squared conditioning). J must have full column rank."""
    if J.shape[1] == 0:
        return np.zeros((0, 0))
    n = J.shape[1]
    # a square upper triangle (a fit's R factor) is its own R: LAPACK's QR would return it unchanged
    triangular = J.shape[0] == n and not np.any(np.tril(J, -1))
    R = np.asarray(J, dtype=float) if triangular else scipy.linalg.qr(J, mode="r")[0][:n]
    Rinv, info = scipy.linalg.lapack.dtrtrs(R, np.eye(n))       # what solve_triangular calls, without its checks
    if info > 0:
        raise np.linalg.LinAlgError("covariance of a rank-deficient Jacobian")
    return sigma2 * (Rinv @ Rinv.T)
