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

    def apply(self, placements, sample: int) -> None:
        """Set the tilted joints' rotations in `placements` (a model's jointPlacements, its joints' translations
        already this ModelState's: BatchKinematics.tilted_model) to those of one sample. Pinocchio 4.1's vector
        hands out references: the rotation is written in place, no SE3 built per sample and joint."""
        R = self.R[sample]
        for k, jid in enumerate(self.joints):
            placements[jid].rotation = R[k]

    def root_placement(self, jid: int, samples: np.ndarray):
        """(R (n, 3, 3), p (3,)) of joint jid's tilted placement at the samples, or None if it does not tilt."""
        if jid not in self.joints:
            return None
        k = self.joints.index(jid)
        return self.R[samples, k], self.p[k]

    def add_terms(self, parts, reg: np.ndarray, samples: np.ndarray, P_joint: np.ndarray, supports) -> None:
        """JointTilts.jacobian's terms for the frame whose parent joint's regressors are `reg` (n, 6, 6 n_joints),
        added to `parts` (JointJacobianParts): the tilt columns, and the placement columns carried through
        exp(-tilt) (placement errors act before the tilt) less what the twist map already gave them. Every tilted
        joint that supports the frame at once (the others' regressor columns are zero)."""
        ks = [k for k, jid in enumerate(self.joints) if jid in supports]
        if not ks:
            return
        n, nk = len(samples), len(ks)
        rows = (6 * (np.array([self.joints[k] for k in ks]) - 1)[:, None] + np.arange(6)).ravel()
        Rt = reg[:, :, rows].reshape(n, 6, nk, 2, 3)          # each joint's columns: translation, rotation half
        P = P_joint[rows]
        cols = np.flatnonzero(np.any(P != 0.0, axis=0))
        if len(cols):
            B = np.swapaxes(self.E[samples][:, ks], -1, -2) - np.eye(3)      # Ad(exp(-tilt)) - I = diag(B, B)
            X = np.einsum("nikaj,nkjl->nikal", Rt, B).reshape(n * 6, 6 * nk)
            parts.add(contiguous(cols), (X @ P[:, cols]).reshape(n, 6, len(cols)))
        tilt_cols = sorted({c for k in ks for c, _ in self.columns[k]})
        if tilt_cols:
            W = np.zeros((nk, len(tilt_cols)))        # tilted joint -> its free column(s), tie coefficients
            for i, k in enumerate(ks):
                for c, w in self.columns[k]:
                    W[i, tilt_cols.index(c)] += w
            v = np.einsum("nikj,nkj->nik", Rt[:, :, :, 1, :], self.d_tilt[samples][:, ks])
            parts.add(contiguous(np.array(tilt_cols)), v @ W)
