"""Joint tilts (robocal.model.joint_tilt) at every sample at once, for the batched pass
(robocal.model.batch_kinematics).

A tilt is a pure rotation of the joint's placement, phi = -t M_perp per sample: exp6([0, phi]) is
(exp3(phi), 0) and Jexp6([0, phi]) is diag(Jexp3(phi), Jexp3(phi)) (its off-diagonal block is linear in
the zero translation). So the tilted placements and JointTilts.jacobian's terms are Rodrigues' formulas
and small products over the samples. The gravity moments M_perp do not depend on the parameters: they are
worked out once per problem (SampleConstants.tilt_moments), not once per pass. What is still per sample is
Pinocchio's: the tilted placements set before each sample's forward kinematics (`apply`).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.model.lie_arrays import TAYLOR_3, skew
from robocal.model.state_layout import contiguous


def rotations(phi: np.ndarray) -> np.ndarray:
    """(..., 3, 3) exp3 of rotation vectors (..., 3) (Rodrigues; Taylor coefficients near 0, as Pinocchio)."""
    theta2 = np.einsum("...i,...i->...", phi, phi)
    theta = np.sqrt(theta2)
    small = theta < TAYLOR_3
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta2 / 6.0 * (1.0 - theta2 / 20.0), np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0 * (1.0 - theta2 / 30.0), 2.0 * (np.sin(0.5 * safe) / safe) ** 2)
    W = skew(phi)
    return np.eye(3) + a[..., None, None] * W + b[..., None, None] * (W @ W)


def right_jacobians(phi: np.ndarray) -> np.ndarray:
    """(..., 3, 3) Jexp3 of rotation vectors (..., 3): exp3(phi + d) = exp3(phi) exp3(Jexp3(phi) d + o(d))."""
    theta2 = np.einsum("...i,...i->...", phi, phi)
    theta = np.sqrt(theta2)
    small = theta < TAYLOR_3
    safe = np.where(small, 1.0, theta)
    b = np.where(small, 0.5 - theta2 / 24.0 * (1.0 - theta2 / 30.0), 2.0 * (np.sin(0.5 * safe) / safe) ** 2)
    c = np.where(small, 1.0 / 6.0 - theta2 / 120.0 * (1.0 - theta2 / 42.0), (safe - np.sin(safe)) / safe ** 3)
    W = skew(phi)
    return np.eye(3) - b[..., None, None] * W + c[..., None, None] * (W @ W)


class TiltArrays:
    """One ModelState's tilted joints (its JointTilts) at every sample of a problem."""

    def __init__(self, tilts, moments: np.ndarray):
        """moments: (n samples, n tilted joints, 3) perpendicular gravity moments, tilts.entries' order."""
        self.joints = [jid for jid, _, _ in tilts.entries]
        self.columns = [cols for _, _, cols in tilts.entries]
        t = np.array([t for _, t, _ in tilts.entries], dtype=float)
        self.key = tuple(t)                          # with the readings, what the tilted placements depend on
        phi = -t[None, :, None] * moments
        self.E = rotations(phi)                                              # (n, k, 3, 3)
        # d(tilt twist)/d t: [0; Jexp3(phi) (-M)], its rotation part (n, k, 3)
        self.d_tilt = np.einsum("nkij,nkj->nki", right_jacobians(phi), -moments)
        base = [tilts.placements[jid] for jid in self.joints]
        self.R = np.einsum("kij,nkjl->nkil", np.array([M.rotation for M in base]), self.E)
        self.p = np.array([M.translation for M in base])
        self._se3: dict[int, list] = {}

    def apply(self, model, sample: int) -> None:
        """Set the tilted joints' placements of `model` (the ModelState's kin_model) to those of one sample."""
        hit = self._se3.get(sample)
        if hit is None:
            hit = self._se3[sample] = [pin.SE3(self.R[sample, k], self.p[k]) for k in range(len(self.joints))]
        for jid, M in zip(self.joints, hit):
            model.jointPlacements[jid] = M

    def root_placement(self, jid: int, samples: np.ndarray):
        """(R (n, 3, 3), p (3,)) of joint jid's tilted placement at the samples, or None if it does not tilt."""
        if jid not in self.joints:
            return None
        k = self.joints.index(jid)
        return self.R[samples, k], self.p[k]

    def add_terms(self, parts, reg: np.ndarray, samples: np.ndarray, P_joint: np.ndarray, supports) -> None:
        """JointTilts.jacobian's terms for the frame whose parent joint's regressors are `reg` (n, 6, 6 n_joints),
        added to `parts` (JointJacobianParts): the tilt columns, and the placement columns carried through
        exp(-tilt) (placement errors act before the tilt) less what the twist map already gave them."""
        for k, jid in enumerate(self.joints):
            if jid not in supports:         # no support of the frame: its regressor columns are zero
                continue
            rows = slice(6 * (jid - 1), 6 * jid)
            Rj = reg[:, :, rows]
            Pj = P_joint[rows]
            cols = np.flatnonzero(np.any(Pj != 0.0, axis=0))
            if len(cols):
                B = np.swapaxes(self.E[samples, k], -1, -2) - np.eye(3)     # Ad(exp(-tilt)) - I: diag(B, B)
                X = np.concatenate([Rj[:, :, :3] @ B, Rj[:, :, 3:] @ B], axis=2)
                n = len(X)
                parts.add(contiguous(cols), (X.reshape(n * 6, 6) @ Pj[:, cols]).reshape(n, 6, len(cols)))
            if self.columns[k]:
                v = np.einsum("nij,nj->ni", Rj[:, :, 3:], self.d_tilt[samples, k])[:, :, None]
                for c, w in self.columns[k]:
                    parts.add(slice(c, c + 1), w * v)
