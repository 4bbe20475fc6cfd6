"""Which parameters the data can determine, and how well.

Base-parameter selection is a greedy pivoted QR on unit-norm columns with a deterministic tie-break:
at each step the column with the largest remaining norm (its distance to the span of the columns
already chosen) is taken; columns whose remaining norm is within a relative `TIE` of the largest count
as tied, and the first in parameter order wins. So parameters that are exact twins (a revolute joint's
offset and its placement's rotation about the same axis) always resolve the same way, whatever
floating-point noise the platform adds. A column is dependent when its remaining norm falls below
`rtol` (1 = orthogonal to everything chosen, 0 = a combination of them).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

TIE = 1e-6


@dataclass
class BaseSelection:
    """Result of `select_base_parameters`.

    independent  column indices kept, in parameter order
    dependent    column indices that the data cannot separate from the kept ones
    regrouping   (len(independent), len(dependent)) with J[:, dependent] ~= J[:, independent] @ regrouping
    condition    condition number of the column-scaled kept block
    singular_values  of the whole column-scaled matrix (largest first)
    """

    names: list[str]
    independent: list[int]
    dependent: list[int]
    regrouping: np.ndarray
    condition: float
    singular_values: np.ndarray
    rtol: float

    @property
    def rank(self) -> int:
        return len(self.independent)

    def confounded_with(self, dependent_index: int, threshold: float = 1e-6) -> list[tuple[str, float]]:
        """(name, coefficient) of kept parameters that a dropped one is a combination of."""
        k = self.dependent.index(dependent_index)
        coef = self.regrouping[:, k]
        scale = np.max(np.abs(coef)) if coef.size else 0.0
        out = [(self.names[i], float(c)) for i, c in zip(self.independent, coef)
               if scale > 0 and abs(c) > threshold * max(scale, 1.0)]
        return sorted(out, key=lambda t: -abs(t[1]))

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


def select_base_parameters(J: np.ndarray, names: list[str] | None = None, rtol: float = 1e-8) -> BaseSelection:
    """Choose a maximal set of columns of J that the data determine (see module doc).

    J: (m, n) Jacobian of the (weighted) residuals; names: n parameter names.
    """
    J = np.asarray(J, dtype=float)
    m, n = J.shape
    names = list(names) if names is not None else [f"p{i}" for i in range(n)]
    norms = np.linalg.norm(J, axis=0)
    live = norms > 0
    scaled = np.zeros_like(J)
    scaled[:, live] = J[:, live] / norms[live]
    # Same column geometry in an n x n matrix: R^T R = J^T J.
    W = scipy.linalg.qr(scaled, mode="r")[0][:n] if m > n else scaled.copy()
    singular = np.linalg.svd(W, compute_uv=False) if n else np.zeros(0)
    chosen: list[int] = []
    basis: list[np.ndarray] = []
    remaining = [j for j in range(n) if live[j]]
    R = W.copy()
    while remaining:
        rn = np.linalg.norm(R[:, remaining], axis=0)
        best = rn.max()
        if best <= rtol:
            break
        j = next(c for c, v in zip(remaining, rn) if v >= best * (1.0 - TIE))
        chosen.append(j)
        remaining.remove(j)
        qv = W[:, j].copy()
        for _ in range(2):  # Gram-Schmidt twice: orthogonal to working precision
            for b in basis:
                qv -= b * (b @ qv)
        qv /= np.linalg.norm(qv)
        basis.append(qv)
        R -= np.outer(qv, qv @ R)
    independent = sorted(chosen)
    dependent = [j for j in range(n) if j not in chosen]
    if independent and dependent:
        beta = np.linalg.lstsq(W[:, independent], W[:, dependent], rcond=None)[0]
        s_in = np.where(live[independent], norms[independent], 1.0)
        regroup = beta / s_in[:, None] * norms[dependent][None, :]
    else:
        regroup = np.zeros((len(independent), len(dependent)))
    if independent:
        sv = np.linalg.svd(W[:, independent], compute_uv=False)
        condition = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    else:
        condition = float("inf")
    return BaseSelection(names, independent, dependent, regroup, condition, singular, rtol)


def covariance(J: np.ndarray, sigma2: float = 1.0) -> np.ndarray:
    """sigma2 * (J^T J)^-1 by QR of J (no squared conditioning). J must have full column rank."""
    if J.shape[1] == 0:
        return np.zeros((0, 0))
    R = scipy.linalg.qr(J, mode="r")[0][: J.shape[1]]
    Rinv = scipy.linalg.solve_triangular(R, np.eye(R.shape[0]))
    return sigma2 * (Rinv @ Rinv.T)
