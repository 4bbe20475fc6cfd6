"""6D pose of a frame (laser tracker with a 6D probe, mocap rigid body, dial-gauge jig).

r = [p - p_meas ; log3(R R_meas^T)], position and rotation errors in the measurement frame.
Per-axis weights: 0 drops an axis (not measured); large weights pin a reference posture.
Measurement columns: x y z qx qy qz qw (unit quaternion, scalar last).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.model.lie_arrays import jlog3, log3, quaternion_matrices, transpose
from robocal.residuals.base import BatchTerms, Residual, Term


class PoseResidual(Residual):
    """6D pose of a frame (laser tracker with a 6D probe, mocap rigid body, dial-gauge jig). The error model,
    parameters and columns: this module's docstring."""

    type_name = "pose"

    def __init__(self, name, frame, samples, measurements, sigma=(1e-4, 1e-4), weights=None, columns=None):
        sig = np.concatenate([np.full(3, np.asarray(sigma).reshape(-1)[0]), np.full(3, np.asarray(sigma).reshape(-1)[-1])])
        super().__init__(name, samples, sig, weights)
        self.frame = frame
        self.columns = list(columns or [f"{name}.{c}" for c in ("x", "y", "z", "qx", "qy", "qz", "qw")])
        self.set_measurements(np.asarray(measurements, dtype=float).reshape(-1, 7))

    dim = 6

    @classmethod
    def column_kinds(cls, n_columns):
        return ["length"] * 3 + [""] * 4
    row_units = ("length",) * 3 + ("angle",) * 3

    def set_measurements(self, m: np.ndarray) -> None:
        q = m[:, 3:7] / np.linalg.norm(m[:, 3:7], axis=1, keepdims=True)
        self.measurements = np.hstack([m[:, :3], q])
        self._R = quaternion_matrices(q)

    def evaluate(self, k, states, aux):
        s = states[self.samples[k]]
        M = s.pose(self.frame)
        R, Rm = M.rotation, self._R[k]
        E = R @ Rm.T
        r = np.concatenate([M.translation - self.measurements[k, :3], pin.log3(E)])
        D = np.zeros((6, 6))
        D[:3, :3] = R
        D[3:, 3:] = pin.Jlog3(E) @ Rm
        return Term(r, [(int(self.samples[k]), self.frame, D)])

    def evaluate_batch(self, terms, R, p, aux):
        Rm = self._R[terms]
        w, theta = log3(R @ transpose(Rm))
        r = np.concatenate([p - self.measurements[terms, :3], w], axis=1)
        D = np.zeros((len(r), 6, 6))
        D[:, :3, :3] = R
        D[:, 3:, 3:] = jlog3(w, theta) @ Rm
        return BatchTerms(r, D)

    def simulate(self, k, states, aux, rng):
        M = states[self.samples[k]].pose(self.frame)
        p = M.translation + rng.normal(0.0, self.sigma[:3])
        R = pin.exp3(rng.normal(0.0, self.sigma[3:])) @ M.rotation
        q = pin.Quaternion(R).coeffs()  # x y z w
        return np.concatenate([p, q])


def pose_row(M: pin.SE3) -> np.ndarray:
    """x y z qx qy qz qw of a pose."""
    return np.concatenate([M.translation, pin.Quaternion(M.rotation).coeffs()])
