"""Sessions: measurements taken on different days, each in its own measurement frame, one robot.

A session is a set of samples measured with one set-up of the instrument. The robot's parameters are shared
by all sessions; the measurement frame (the tracker's placement, `base`) may be re-registered per session:
session s (after the first, the reference) sees every frame pose as T_s M, with T_s = exp6(xi_s) a left
correction of the measurement frame, and xi_s = `base@<session>.tx ... .rz` its six parameters (kind
"session_frame", m and rad). The first session's frame is the config's `base` itself.

A residual knows only the poses it is given (`SampleState.pose`), so sessions need no change to any
measurement type: the problem hands each residual the corrected poses (`SessionStates`, `session_arrays`),
and adds the correction's own Jacobian columns. For a residual derivative D with respect to the LOCAL
twist of the corrected pose T_s M, since exp6(xi + dxi) = exp6(xi) exp6(Jexp6(xi) dxi) and
exp6(eta) M = M exp6(Ad(M^-1) eta),

    dr/dxi_s = D Ad(M^-1) Jexp6(xi_s)   (M the pose before the correction, in the shared measurement frame)

See docs/validation.md, "Sessions".
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.model.parameters import COMPONENTS, Parameter

#: the frame a session may re-register: the measurement frame (the instrument's placement)
SESSION_FRAMES = ("base",)
KIND = "session_frame"


@dataclass(frozen=True)
class Sessions:
    """names: the sessions in order (the first is the reference); of_sample: (N,) the session of each sample;
    frames: the frames re-registered in every session (SESSION_FRAMES)."""

    names: tuple[str, ...]
    of_sample: np.ndarray
    frames: tuple[str, ...] = ("base",)

    def __post_init__(self):
        unknown = [f for f in self.frames if f not in SESSION_FRAMES]
        if unknown:
            raise ValueError(f"a session re-registers {', '.join(SESSION_FRAMES)} only, not {', '.join(unknown)}")

    @property
    def corrected(self) -> bool:
        """Whether any session has its own frame (two or more sessions and a re-registered frame)."""
        return len(self.names) > 1 and bool(self.frames)

    def parameter_names(self, session: int) -> list[str]:
        """The six correction parameters of a session after the first (none for the reference)."""
        if session == 0 or not self.frames:
            return []
        return [f"base@{self.names[session]}.{c}" for c in COMPONENTS]

    def parameters(self) -> list[Parameter]:
        """Every session's correction parameters, at zero (free)."""
        out = []
        for s in range(1, len(self.names)):
            for c, name in zip(COMPONENTS, self.parameter_names(s)):
                out.append(Parameter(name, KIND, f"base@{self.names[s]}", COMPONENTS.index(c),
                                     unit="m" if c.startswith("t") else "rad"))
        return out

    def samples_of(self, session: int) -> np.ndarray:
        return np.flatnonzero(self.of_sample == session)

    def subset(self, keep: np.ndarray) -> "Sessions":
        """The sessions of a subset of the samples (renumbered as the subset's samples)."""
        return Sessions(self.names, np.asarray(self.of_sample)[np.asarray(keep, dtype=int)], self.frames)


def session_twists(sessions: Sessions, params) -> np.ndarray:
    """(S, 6) xi_s of every session at the parameters' current values (zero for the reference)."""
    out = np.zeros((len(sessions.names), 6))
    for s in range(len(sessions.names)):
        names = sessions.parameter_names(s)
        if names:
            out[s] = [params[n].value for n in names]
    return out


def corrections(sessions: Sessions, params) -> list[pin.SE3]:
    """T_s = exp6(xi_s) of every session (identity for the reference)."""
    return [pin.exp6(xi) for xi in session_twists(sessions, params)]


def exp_jacobians(sessions: Sessions, params) -> np.ndarray:
    """(S, 6, 6) Jexp6(xi_s): how the correction's LOCAL twist moves with its parameters."""
    return np.array([pin.Jexp6(xi) for xi in session_twists(sessions, params)])


class SessionStates:
    """states[i] for residuals: sample i's state whose poses are corrected by its session's T_s."""

    def __init__(self, states, sessions: Sessions, T: list[pin.SE3]):
        self.raw, self.sessions, self.T = states, sessions, T

    def __getitem__(self, i):
        return CorrectedState(self.raw[i], self.T[int(self.sessions.of_sample[int(i)])])

    def __len__(self):
        return len(self.raw)


class CorrectedState:
    """A SampleState seen from its session's measurement frame: pose() corrected, the rest unchanged (a left
    correction leaves every LOCAL twist, hence every parameter Jacobian, as it is)."""

    def __init__(self, state, T: pin.SE3):
        self.state, self.T = state, T

    def pose(self, frame) -> pin.SE3:
        return self.T * self.state.pose(frame)

    def __getattr__(self, name):
        return getattr(self.state, name)


def correction_jacobian(D: np.ndarray, M: pin.SE3, Jexp: np.ndarray) -> np.ndarray:
    """dr/dxi (d, 6) of a session's correction, for D = dr/d(LOCAL twist of T M) (d, 6), M uncorrected,
    Jexp = Jexp6(xi) of that session."""
    return D @ M.inverse().toActionMatrix() @ Jexp


def session_arrays(R: np.ndarray, p: np.ndarray, T: list[pin.SE3], session: np.ndarray):
    """(R', p') = T_s (R, p) for n poses (n, 3, 3), (n, 3), the session of each in `session` (n,)."""
    Rs = np.array([t.rotation for t in T])[session]
    ps = np.array([t.translation for t in T])[session]
    return Rs @ R, np.einsum("nij,nj->ni", Rs, p) + ps


def correction_jacobians(D: np.ndarray, R: np.ndarray, p: np.ndarray, Jexp: np.ndarray) -> np.ndarray:
    """(n, d, 6) D Ad(M^-1) Jexp6 for n derivatives D (n, d, 6), uncorrected poses M = (R, p) and each term's
    session's Jexp6 (n, 6, 6): the batched correction_jacobian. Ad(M^-1) = [[R^T, -R^T [p]x], [0, R^T]] in
    Pinocchio's (v, w) order."""
    Rt = np.transpose(R, (0, 2, 1))
    px = np.zeros((len(p), 3, 3))
    px[:, 0, 1], px[:, 0, 2], px[:, 1, 2] = -p[:, 2], p[:, 1], -p[:, 0]
    px[:, 1, 0], px[:, 2, 0], px[:, 2, 1] = p[:, 2], -p[:, 1], p[:, 0]
    out = np.empty(D.shape)
    out[:, :, :3] = D[:, :, :3] @ Rt
    out[:, :, 3:] = D[:, :, 3:] @ Rt - D[:, :, :3] @ (Rt @ px)
    return out @ Jexp
