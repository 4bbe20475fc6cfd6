"""Stewart (6-UPS) forward kinematics: Newton on the closed-form IK, one pose or a batch.

The single-pose solver is written against numpy's per-call overhead (~0.3-1 us per call on 6-vectors,
more than the arithmetic), so each Newton step is about a dozen calls:

* state = the inverse platform pose Minv (4, 4); every strut vector l_j = R^T (p - N_j) + T_j and every
  entry of the unnormalised IK Jacobian [l_j, T_j x l_j] is LINEAR in the 16 entries of Minv, so one
  precomputed (54, 16) matrix gives both from Minv.ravel() in a single product;
* Newton runs on the squared lengths F_j = |l_j|^2 - (o_j + s_j)^2 (no square roots; dF/dxi = 2 J_u),
  whose root is the same pose; the stopping test uses the strut-length error F_j / (2 (o_j + s_j));
* the local twist update M <- M exp6(xi) is Minv <- exp6(-xi) Minv: one small product.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from scipy.linalg.lapack import dgesv

from robocal.errors import AssemblyError

QUADRATIC_FINISH = 1e-7   # m: strut-length error below which one more Newton step lands inside 1e-12
WELL_CONDITIONED = 1e-3   # smallest / largest LU pivot of the IK Jacobian above which that finish is trusted
ONES6 = np.ones(6)


class NewtonTables(NamedTuple):
    """Constants of the single-pose FK of one geometry (built once, in StewartGeometry)."""
    lift: np.ndarray          # (54, 16): Minv.ravel() -> [l (18,), (2 J_u)^T (36,)]
    sum3: np.ndarray          # (18, 6): squared components -> squared lengths
    home_inv: np.ndarray      # (4, 4) inverse home pose
    home_sq: np.ndarray       # (6,) squared strut vector lengths at home
    home_step: np.ndarray | None   # (6, 6) (2 J_u(home))^-1; None if home is singular


def newton_tables(leg_base: np.ndarray, leg_platform: np.ndarray, home: np.ndarray,
                  jac_map: np.ndarray) -> NewtonTables:
    """Tables for `forward_kinematics`; jac_map (36, 18) maps the stacked l to the rows [l_j, T_j x l_j]."""
    # l_j[i] = -sum_k Minv[i, k] N_j[k] - Minv[i, 3] + T_j[i] Minv[3, 3]   (Minv[3, 3] = 1)
    to_l = np.zeros((18, 16))
    for j in range(6):
        for i in range(3):
            to_l[3 * j + i, 4 * i:4 * i + 3] = -leg_base[j]
            to_l[3 * j + i, 4 * i + 3] = -1.0
            to_l[3 * j + i, 15] = leg_platform[j, i]
    # 2 J_u stored transposed, so that reshape(6, 6).T is the matrix itself
    to_jac = (2.0 * jac_map @ to_l).reshape(6, 6, 16).transpose(1, 0, 2).reshape(36, 16)
    home_inv = pin.SE3(np.eye(3), np.asarray(home, float)).inverse().homogeneous
    lifted = np.vstack([to_l, to_jac]) @ home_inv.ravel()
    l_home = lifted[:18].reshape(6, 3)
    try:
        home_step = np.linalg.inv(lifted[18:].reshape(6, 6).T)
    except np.linalg.LinAlgError:
        home_step = None   # singular home pose: FK starts with plain Newton steps
    return NewtonTables(np.vstack([to_l, to_jac]), np.kron(np.eye(6), np.ones((3, 1))), home_inv,
                        (l_home * l_home).sum(1), home_step)


def forward_kinematics(geometry, s, guess: pin.SE3 | None = None, tol: float = 1e-12,
                       max_iter: int = 30, sample=None, singular_ratio: float = 1e-5) -> pin.SE3:
    """Platform pose (world SE3) from strut coordinates s (6,) by damped Newton on the IK.

    guess: warm start (e.g. the previous sample's pose), home pose by default. Converges when the
    strut-length error has 2-norm < tol (m). Raises AssemblyError naming `sample` if the struts
    cannot be assembled, or if the pose is singular (Hadamard ratio |det J| / prod |row_j| of the
    IK Jacobian below singular_ratio).
    """
    lift, sum3, home_inv, home_sq, home_step = geometry._fk
    label = f"sample {sample}" if sample is not None else "the given strut coordinates"
    target = np.asarray(s, dtype=float) + geometry.offsets
    shortest = min(target.tolist())   # a Python reduction: cheaper than numpy's on 6 numbers
    if not shortest > 0.0:   # |l| = |target| would accept a negative target
        raise AssemblyError(f"{label}: Stewart FK got a non-positive strut length o + s; the strut "
                            "coordinates are out of reach")
    target2 = target * target
    # |l_j| - t_j = F_j / (|l_j| + t_j) ~ F_j / (2 t_j), so |F| < 2 min(t) eps bounds the length error by eps
    scale2 = 4.0 * shortest * shortest
    tol2, finish2 = scale2 * tol * tol, scale2 * QUADRATIC_FINISH ** 2
    # x = -xi solves (2 J_u) x = F, and Minv <- exp6(x) Minv applies the twist xi
    prev, x, alpha, best, lu, jac = None, None, 1.0, np.inf, None, None
    if guess is None and home_step is not None:
        # cold start: the first Newton step from home is a fixed linear map of the squared lengths
        f = home_sq - target2
        prev, best, x = home_inv, f.dot(f), home_step.dot(f)
        Minv = pin.exp6(x).homogeneous.dot(home_inv)
    elif guess is None:
        Minv = home_inv
    else:
        Minv = guess.inverse().homogeneous
    for _ in range(max_iter):
        out = lift.dot(Minv.ravel())
        sq = out[:18]
        f = (sq * sq).dot(sum3) - target2
        cost = f.dot(f)
        if cost < tol2:
            if lu is None:  # converged at the start: factor once, for the singularity check
                jac = out[18:].reshape(6, 6).T
                lu = dgesv(jac, f)[0]
            # Hadamard ratio |det| / prod |row_j| of the last factored Jacobian (<= 1e-6 away: same
            # conditioning), |det| = |prod of the LU pivots|; Python products: 6 numbers
            det = abs(math.prod(lu.diagonal().tolist()))
            if det < singular_ratio * math.sqrt(math.prod((jac * jac).dot(ONES6).tolist())):
                raise AssemblyError(f"{label}: Stewart FK converged to a singular pose")
            return pin.SE3(Minv).inverse()
        if cost >= best:  # no decrease: halve the last step from the last good pose
            alpha *= 0.5
            if alpha < 1e-6:
                break
            Minv = pin.exp6(alpha * x).homogeneous.dot(prev)
            continue
        best, alpha, prev = cost, 1.0, Minv
        jac = out[18:].reshape(6, 6).T
        lu, _piv, x, info = dgesv(jac, f)
        if info != 0:
            raise AssemblyError(f"{label}: Stewart FK met a singular pose (struts cannot fix the platform)")
        Minv = pin.exp6(x).homogeneous.dot(Minv)
        if cost < finish2 and tol >= 1e-12:
            # Newton is quadratic where the Jacobian is well conditioned: from |e| < 1e-7 m the full step
            # leaves ~|e|^2 / l ~ 1e-14 m, 100 times inside tol, so the confirming evaluation is skipped.
            # Near a singular pose convergence is slow and the loop goes on (and reports it).
            pivots = np.abs(lu.diagonal()).tolist()
            if min(pivots) > WELL_CONDITIONED * max(pivots):
                return pin.SE3(Minv).inverse()
    lengths = np.sqrt((sq * sq).dot(sum3))
    raise AssemblyError(f"{label}: Stewart FK did not converge (strut error "
                        f"{np.linalg.norm(lengths - target):.3g} m); the strut coordinates are out of "
                        "reach or singular")


def _exp3_batch(w: np.ndarray) -> np.ndarray:
    """Rodrigues' formula for rotation vectors w (K, 3) -> (K, 3, 3)."""
    theta2 = np.einsum("ki,ki->k", w, w)
    theta = np.sqrt(theta2)
    small = theta < 1e-6
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    K = np.zeros((w.shape[0], 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    return np.eye(3) + a[:, None, None] * K + b[:, None, None] * (K @ K)


def forward_kinematics_batch(geometry, s: np.ndarray, R0: np.ndarray | None = None,
                             p0: np.ndarray | None = None, tol: float = 1e-12, max_iter: int = 30,
                             strict: bool = True):
    """Vectorised Newton FK for K samples of strut coordinates s (K, 6).

    R0 (K, 3, 3), p0 (K, 3): warm starts (home pose by default). Returns R (K, 3, 3), p (K, 3) and
    converged (K,) bool (strut-length error 2-norm < tol). With strict=True a sample that does not
    converge raises AssemblyError naming it (no damping here: use `forward_kinematics` for hard cases).
    """
    s = np.atleast_2d(np.asarray(s, dtype=float))
    k = s.shape[0]
    R = np.broadcast_to(np.eye(3), (k, 3, 3)).copy() if R0 is None else np.array(R0, dtype=float)
    p = np.broadcast_to(geometry.home, (k, 3)).copy() if p0 is None else np.array(p0, dtype=float)
    target = s + geometry.offsets
    active = np.arange(k)
    for it in range(max_iter + 1):
        Ra, pa = R[active], p[active]
        d = (pa[:, None, :] - geometry.leg_base) @ Ra + geometry.leg_platform   # local strut vectors
        lengths = np.sqrt(np.einsum("kji,kji->kj", d, d))
        e = lengths - target[active]
        todo = np.einsum("kj,kj->k", e, e) >= tol * tol
        if not todo.all():
            active, d, lengths, e, Ra, pa = active[todo], d[todo], lengths[todo], e[todo], Ra[todo], pa[todo]
        if active.size == 0 or it == max_iter:
            break
        ju = (d.reshape(-1, 18) @ geometry._jac_map.T).reshape(-1, 6, 6)
        rhs = -(lengths * e)[..., None]
        try:
            step = np.linalg.solve(ju, rhs)[..., 0]
        except np.linalg.LinAlgError:  # a singular sample: least squares, it stays unconverged
            step = (np.linalg.pinv(ju) @ rhs)[..., 0]
        p[active] = pa + (Ra @ step[:, :3, None])[..., 0]
        R[active] = Ra @ _exp3_batch(step[:, 3:])
    converged = np.ones(k, dtype=bool)
    converged[active] = False
    if strict and active.size:
        raise AssemblyError(f"samples {active[:10].tolist()}{' ...' if active.size > 10 else ''}: Stewart FK "
                            "did not converge (strut coordinates out of reach or singular)")
    return R, p, converged
