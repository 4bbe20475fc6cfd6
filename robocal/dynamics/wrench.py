"""Joint torques -> wrench at a frame (the patent's Eq. 4), batched and damped near singularities.

C_ext = J^T F, J the (6, n) frame Jacobian in LOCAL_WORLD_ALIGNED axes, F = [force; moment about
the frame origin] of the robot on its environment. The mapper solves
    F = (J J^T + lambda^2 I)^-1 J C_ext
which is J^-T C_ext for a square well-conditioned J (lambda = 0, solved directly), the least
squares fit for n > 6, and damped least squares near a singularity. The damping follows the
usual smooth rule: lambda^2 = lambda_max^2 (1 - (sigma_min/sigma_0)^2) when sigma_min < sigma_0.
The 2-norm condition number of J is returned for every sample.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError


@dataclass
class WrenchEstimate:
    """Batch result. wrench (T, 6) [N, N m]; condition (T,) cond_2(J); damped (T,) bool (lambda > 0);
    ill_conditioned (T,) bool (condition above the mapper's threshold); residual (T, n) N m, the part
    of C_ext no wrench explains (non-zero for n > 6, damping or the force-only model)."""

    wrench: np.ndarray
    condition: np.ndarray
    damped: np.ndarray
    ill_conditioned: np.ndarray
    residual: np.ndarray

    @property
    def force(self) -> np.ndarray:
        return self.wrench[:, :3]


@dataclass
class WrenchMapper:
    """sigma_threshold: smallest singular value of J (mixed units: m/rad rows and 1/rad rows) below
    which damping starts; damping_max: lambda_max; condition_threshold: flag level for cond(J);
    force_only: fit F = [f; 0] (3 unknowns) instead of the full wrench."""

    sigma_threshold: float = 1e-3
    damping_max: float = 1e-2
    condition_threshold: float = 1e3
    force_only: bool = False

    def __post_init__(self):
        if not (self.sigma_threshold > 0 and self.damping_max > 0 and self.condition_threshold > 1):
            raise InputError("wrench mapper needs sigma_threshold > 0, damping_max > 0 (so a singular "
                             "Jacobian stays solvable) and condition_threshold > 1",
                             field="sigma_threshold")

    def map(self, jacobians: np.ndarray, joint_torques: np.ndarray) -> WrenchEstimate:
        """jacobians (T, 6, n), joint_torques (T, n) N m -> WrenchEstimate."""
        J = np.asarray(jacobians, dtype=float)
        tau = np.asarray(joint_torques, dtype=float)
        if J.ndim != 3 or J.shape[1] != 6 or tau.shape != (J.shape[0], J.shape[2]):
            raise InputError(f"expected jacobians (T, 6, n) and torques (T, n); got {J.shape}, {tau.shape}",
                             field="jacobians")
        A = J @ J.transpose(0, 2, 1)
        eig = np.linalg.eigvalsh(A)                     # ascending, sigma^2
        sig_min = np.sqrt(np.clip(eig[:, 0], 0.0, None))
        sig_max = np.sqrt(np.clip(eig[:, -1], 0.0, None))
        with np.errstate(divide="ignore"):
            condition = np.where(sig_min > 0, sig_max / np.where(sig_min > 0, sig_min, 1.0), np.inf)
        ratio = sig_min / self.sigma_threshold
        lam2 = np.where(ratio < 1.0, self.damping_max**2 * (1.0 - ratio**2), 0.0)
        damped = lam2 > 0
        if self.force_only:
            wrench = self._force_only(J, tau)
        else:
            wrench = np.empty((J.shape[0], 6))
            square = J.shape[2] == 6
            plain = ~damped if square else np.zeros(J.shape[0], bool)
            if plain.any():   # exact J^-T, avoids squaring the condition number
                wrench[plain] = np.linalg.solve(J[plain].transpose(0, 2, 1), tau[plain, :, None])[..., 0]
            rest = ~plain
            if rest.any():
                Ar = A[rest] + lam2[rest, None, None] * np.eye(6)
                wrench[rest] = np.linalg.solve(Ar, (J[rest] @ tau[rest, :, None]))[..., 0]
        residual = tau - (J.transpose(0, 2, 1) @ wrench[:, :, None])[..., 0]
        return WrenchEstimate(wrench, condition, damped, condition > self.condition_threshold, residual)

    def map_one(self, J: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, float, bool]:
        """One sample, same rule as `map` with less overhead (the control tick):
        J (6, n), tau (n,) -> (wrench (6,), cond(J), damped)."""
        if self.force_only:
            w = self.map(J[None], tau[None])
            return w.wrench[0], float(w.condition[0]), bool(w.damped[0])
        sig = np.linalg.svd(J, compute_uv=False)
        sig_min = sig[5] if sig.size >= 6 else 0.0
        cond = sig[0] / sig_min if sig_min > 0 else np.inf
        ratio = sig_min / self.sigma_threshold
        if ratio >= 1.0 and J.shape[1] == 6:
            return np.linalg.solve(J.T, tau), float(cond), False
        lam2 = self.damping_max**2 * (1.0 - ratio**2) if ratio < 1.0 else 0.0
        wrench = np.linalg.solve(J @ J.T + lam2 * np.eye(6), J @ tau)
        return wrench, float(cond), lam2 > 0

    def _force_only(self, J: np.ndarray, tau: np.ndarray) -> np.ndarray:
        Jl = J[:, :3, :]
        f = np.linalg.solve(Jl @ Jl.transpose(0, 2, 1), (Jl @ tau[:, :, None]))[..., 0]
        return np.concatenate([f, np.zeros_like(f)], axis=1)
