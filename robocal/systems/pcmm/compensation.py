"""Using an identified 4-PUU CMM: corrected measurements, corrected commands, and its validation up to
the gauge (a rigid transform that no artefact can see). Units: SI (m, rad). See docs/pcmm_calibration.md.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.systems.pcmm.kinematics import (PCMMGeometry, forward_kinematics, inverse_kinematics,
                                             pose_error_jacobian, rz, tip_points)


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
    """(N, 4) pose correction J_p d_eps at the nominal FK poses (first order, measurement mode)."""
    return np.einsum("nak,k->na", pose_error_jacobian(nominal, poses, readings), np.asarray(d_eps, dtype=float))


# ---- validation up to the gauge ----------------------------------------------------------------
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
