"""Levenberg-Marquardt on an analytic Jacobian, with robust losses and a convergence record.

Written here rather than taken from scipy.optimize.least_squares because robocal needs what that
does not offer together: one robust weight per measurement term (a 3D point or a 6D pose is one
outlier, not three or six), a per-iteration record for the progress display and the report, and
box bounds with the 'lm' method. Names follow scipy (x, cost, fun, jac, status, message, success,
ftol/xtol/gtol, loss, f_scale).

Step: (J^T J + lam D^2) dx = -J^T r, solved through the QR factor of J (no squared conditioning);
D holds Marquardt's column scales (the largest column norms seen so far). One QR per accepted point, of
[J r] (R only, no Q): its triangle T = [[R, Q^T r], [0, .]] gives the step, the gradient R^T Q^T r, the
predicted reduction and the column norms, and the last one is returned for the caller's final parameter
selection and covariance. A Jacobian too large to hold may be any object with `triangle(weights)` that
returns T itself (robocal.estimation.chunked_lstsq accumulates it chunk by chunk).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.linalg
import scipy.linalg.lapack

from robocal.errors import AssemblyError

LOSSES = ("linear", "huber", "soft_l1")


@dataclass
class Iteration:
    iteration: int
    cost: float
    step_norm: float
    damping: float
    gradient_norm: float


@dataclass
class SolveResult:
    x: np.ndarray
    cost: float
    fun: np.ndarray
    jac: np.ndarray
    status: int
    message: str
    nit: int
    history: list[Iteration] = field(default_factory=list)
    weights: np.ndarray | None = None    # robust row weights at the solution (1 for the linear loss)
    triangle: np.ndarray | None = None   # (n+1, n+1) R factor of [J r] * weights at x (see module doc)

    @property
    def success(self) -> bool:
        return self.status > 0


def robust_weights(r: np.ndarray, group: np.ndarray, loss: str, f_scale: float) -> tuple[np.ndarray, float]:
    """Row weights sqrt(rho'(s_g)) and the cost 1/2 sum d_g rho(s_g).

    s_g is the mean square per row of term g (d_g rows), so the knee f_scale means the same, in sigmas,
    for a 1-row contact and a 6-row pose.
    """
    if not len(r):
        return np.zeros(0), 0.0
    d = np.bincount(group).astype(float)
    s = np.bincount(group, weights=r * r) / np.maximum(d, 1.0)
    c2 = f_scale ** 2
    if loss == "linear":
        rho, drho = s, np.ones_like(s)
    elif loss == "huber":
        big = s > c2
        rho = np.where(big, 2.0 * f_scale * np.sqrt(s) - c2, s)
        drho = np.where(big, f_scale / np.sqrt(np.maximum(s, c2)), 1.0)
    elif loss == "soft_l1":
        t = np.sqrt(1.0 + s / c2)
        rho, drho = 2.0 * c2 * (t - 1.0), 1.0 / t
    else:
        raise ValueError(f"unknown loss '{loss}'; use one of {LOSSES}")
    return np.sqrt(drho)[group], 0.5 * float((d * rho).sum())


def levenberg_marquardt(fun: Callable, x0: np.ndarray, lower=None, upper=None, loss: str = "linear",
                        f_scale: float = 1.0, max_iterations: int = 100, ftol: float = 1e-12,
                        xtol: float = 1e-12, gtol: float = 1e-10, callback: Callable | None = None,
                        first_triangle: np.ndarray | None = None) -> SolveResult:
    """Minimise 1/2 sum rho(|r_g|^2) over x within [lower, upper].

    fun(x) -> (r, J, group): residual (m,), Jacobian (m, n), term id of each row (m,).
    callback(Iteration) is called after every accepted step.
    first_triangle: the triangle of [J r] at x0 if the caller has it (used with the linear loss, whose
    weights are 1; the caller's factorisation then serves the first step too).
    """
    n = len(x0)
    lower = np.full(n, -np.inf) if lower is None else np.asarray(lower, float)
    upper = np.full(n, np.inf) if upper is None else np.asarray(upper, float)
    x = np.clip(np.asarray(x0, float), lower, upper)
    r, J, group = fun(x)
    w, cost = robust_weights(r, group, loss, f_scale)
    cost0 = cost
    unit = loss == "linear"          # all weights 1: no weighted copy
    T = (first_triangle if unit and first_triangle is not None and np.array_equal(x, x0)
         else triangle(J, r, None if unit else w, n))
    R, qtr = T[:n, :n], T[:n, n]
    D = np.maximum(np.linalg.norm(R, axis=0), 1e-12)
    lam, history, good_model = 1e-3, [], False
    status, message = 0, "maximum number of iterations reached"

    def result(status, message, it):
        return SolveResult(x, cost, r, J, status, message, it, history, w, T)

    for it in range(1, max_iterations + 1):
        g = R.T @ qtr
        gnorm = float(np.max(np.abs(g / D))) if n else 0.0
        if n == 0 or gnorm <= gtol * max(1.0, np.sqrt(2 * cost)):
            status, message = 1, "gradient below gtol"
            break
        # 1/2 |Q^T r|^2 is the reduction the Gauss-Newton step predicts, the most the linear model can gain
        # (rank deficiency and bounds only lower it). Once the model has predicted the last step well, a
        # prediction below ftol x cost means the step cannot pass the ftol test below: stop without
        # evaluating it (it would move the parameters by a fraction of a standard error of order sqrt(ftol))
        if good_model and 0.5 * float(qtr @ qtr) <= ftol * cost:
            status, message = 2, "cost reduction below ftol"
            break
        # After a step the model predicted well, try the undamped (Gauss-Newton) step first: on a
        # well-modelled but ill-conditioned problem the damping would otherwise hold back the weak
        # directions for many iterations while it decays.
        undamped = good_model
        while True:
            dx = lm_step(R, qtr, D, 0.0 if undamped else lam)
            x_new = np.clip(x + dx, lower, upper)
            dx = x_new - x
            try:
                r_new, J_new, _ = fun(x_new)
                w_new, cost_new = robust_weights(r_new, group, loss, f_scale)
            except AssemblyError:
                # a closed chain that does not assemble at the trial parameters: too long a step
                r_new = J_new = w_new = None
                cost_new = np.inf
            predicted = -(g @ dx) - 0.5 * np.sum((R @ dx) ** 2)
            if undamped:
                undamped = False
                if cost_new < cost and predicted > 0 and (cost - cost_new) > 0.25 * predicted:
                    break
                continue
            if cost_new < cost or (cost_new <= cost and predicted <= 0):
                break
            if np.linalg.norm(D * dx) <= xtol * (np.linalg.norm(D * x) + xtol):
                # a rejected step that is already negligible: the minimum is found to working precision
                return result(3, "step below xtol", it)
            if cost <= 1e-28 * cost0 or (predicted <= 1e-14 * cost and 0.5 * float(qtr @ qtr) <= 1e-12 * cost):
                # even the undamped model predicts nothing to gain: the fit is exact to rounding (noise-free
                # data). A damped prediction alone shrinks with the damping whatever the Jacobian: a wrong
                # Jacobian would end here as a success; it goes on to the damping cap and fails instead
                return result(4, "cost at the rounding level", it)
            lam *= 4.0
            if lam > 1e16:
                return result(-1, "no step reduces the cost (local minimum or bad Jacobian)", it)
        gain = (cost - cost_new) / predicted if predicted > 0 else 0.0
        good_model = gain > 0.75
        lam = lam * max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3) if gain > 0 else lam * 2.0
        step = float(np.linalg.norm(D * dx))
        reduction = cost - cost_new
        x, r, J, cost = x_new, r_new, J_new, cost_new
        w = w_new
        T = triangle(J, r, None if unit else w, n)
        R, qtr = T[:n, :n], T[:n, n]
        D = np.maximum(D, np.linalg.norm(R, axis=0))
        rec = Iteration(it, cost, step, lam, gnorm)
        history.append(rec)
        if callback:
            callback(rec)
        if step <= xtol * (np.linalg.norm(D * x) + xtol):
            status, message = 3, "step below xtol"
            break
        if reduction <= ftol * max(cost + reduction, 1e-300):
            status, message = 2, "cost reduction below ftol"
            break
    else:
        it = max_iterations
    return result(status, message, it)


STEP_RCOND = 1e-10   # R's estimated reciprocal condition above which its triangle solves the undamped step


def lm_step(R: np.ndarray, qtr: np.ndarray, D: np.ndarray, damping: float) -> np.ndarray:
    """The least-squares solution dx of [R; sqrt(damping) D] dx = [-qtr; 0] (D: diagonal scales, > 0).

    Damped: one QR of the (2n, n+1) augmented system (LAPACK geqrf) and a triangular solve. Undamped: the
    triangular solve with R itself when it is well-conditioned (LAPACK trcon's estimate), else the
    minimum-norm solution (lstsq). The same solution as lstsq of the stacked system, to rounding, at a
    fraction of its cost on the small triangles of a fit (~10-25 against ~85 us at 31 columns)."""
    n = len(qtr)
    if n == 0:
        return np.zeros(0)
    if damping == 0.0:
        rcond, info = scipy.linalg.lapack.dtrcon(R, norm="1", uplo="U", diag="N")
        if info == 0 and rcond > STEP_RCOND:
            return scipy.linalg.lapack.dtrtrs(R, -qtr)[0]
        return np.linalg.lstsq(R, -qtr, rcond=None)[0]
    A = np.zeros((2 * n, n + 1), order="F")
    A[:n, :n] = R
    A[:n, n] = -qtr
    A[np.arange(n, 2 * n), np.arange(n)] = np.sqrt(damping) * D
    qr, _tau, _work, info = scipy.linalg.lapack.dgeqrf(A, overwrite_a=True)
    if info != 0:
        raise ValueError(f"LAPACK dgeqrf failed (info {info})")
    return scipy.linalg.lapack.dtrtrs(qr[:n, :n], qr[:n, n])[0]


QR_ROWS = 2000   # rows per block of `triangle`: a block's QR stays in cache (measured ~1.6x faster at 60000 rows)


def triangle(J, r: np.ndarray, w: np.ndarray | None, n: int, rows: np.ndarray | None = None) -> np.ndarray:
    """(n+1, n+1) upper-triangular T with T^T T = [J r]^T W^2 [J r] (W = diag(w), none: 1) over `rows` (a
    boolean mask; default all), or J.triangle(w, rows) for a Jacobian kept as chunks.

    Blocked (TSQR): each block of QR_ROWS rows is copied with its weights into one small column-major work
    array and factored there, and the stacked block triangles are factored once more. No full-size copy of J
    is made and the result equals one QR of the whole to rounding."""
    if hasattr(J, "triangle"):
        return J.triangle(w, rows)
    index = None if rows is None or rows.all() else np.flatnonzero(rows)
    m = len(r) if index is None else len(index)
    k = n + 1
    blocks = range(0, m, QR_ROWS)
    stacked = np.zeros((max(len(blocks), 1) * k, k), order="F")
    work = np.empty((min(m, QR_ROWS), k), order="F")
    for b, start in enumerate(blocks):
        part = slice(start, min(start + QR_ROWS, m))
        take = part if index is None else index[part]
        size = part.stop - part.start
        A = work if size == len(work) else np.empty((size, k), order="F")
        if w is None:
            np.copyto(A[:, :n], J[take])
            A[:, n] = r[take]
        else:
            wb = w[take]
            np.multiply(J[take], wb[:, None], out=A[:, :n])
            np.multiply(r[take], wb, out=A[:, n])
        stacked[b * k:(b + 1) * k] = r_factor(A, overwrite=True)
    return stacked[:k] if len(blocks) <= 1 else r_factor(stacked, overwrite=True)


QR_PANEL = 8         # geqrt's block size, for blocks wider than UNBLOCKED_QR
UNBLOCKED_QR = 80    # columns up to which plain Householder QR (geqrf, which LAPACK runs unblocked below 128
                     # columns) is faster on a fit's blocks than compact-WY geqrt: measured on 2000-row blocks
                     # 20 against 25 ms at 55 columns, 7 against 12 at 31, 1.5 against 3.9 at 13; slower from
                     # ~100 columns (docs/speed.md)


def r_factor(A: np.ndarray, overwrite: bool = False) -> np.ndarray:
    """(k, k) upper-triangular R with R^T R = A^T A for an (m, k) array (rows of zeros below when m < k).
    LAPACK geqrf (narrow A) or geqrt (compact-WY QR with small panels) on a column-major copy of A, or on A
    itself when it is column-major and `overwrite`: much faster than scipy.linalg.qr(mode='r'), which copies A
    and returns the full (m, k) R."""
    m, k = A.shape
    R = np.zeros((0, k))
    if m and k:
        work = np.array(A, order="F", copy=None if overwrite else True)
        if k <= UNBLOCKED_QR:
            qr, _tau, _work, info = scipy.linalg.lapack.dgeqrf(work, overwrite_a=True)
        else:
            qr, _t, info = scipy.linalg.lapack.dgeqrt(max(1, min(QR_PANEL, m, k)), work, overwrite_a=True)
        if info != 0:
            raise ValueError(f"LAPACK QR failed (info {info})")
        R = qr[:k].copy()
        R[_below_diagonal(R.shape)] = 0.0      # np.triu's result, without its mask built at every call
    return np.vstack([R, np.zeros((k - len(R), k))]) if len(R) < k else R


_MASKS: dict = {}


def _below_diagonal(shape: tuple[int, int]) -> np.ndarray:
    mask = _MASKS.get(shape)
    if mask is None:
        if len(_MASKS) > 64:       # a handful of shapes a fit; bounded in a long-running process
            _MASKS.clear()
        mask = _MASKS[shape] = np.tril(np.ones(shape, dtype=bool), -1)
    return mask
