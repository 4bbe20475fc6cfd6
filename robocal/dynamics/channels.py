"""What the identification's rows are: the torques of recorded joints, or of logged motors through a
transmission (transmission.py).

Without a transmission each row is a recorded joint's equation, tau_j = Y_j pi + the joint's terms.
With one, each row is a logged motor's:
    tau_m_k = sum_j T[j, k] (Y_j pi + joint j's terms) + J_k mddot_k + Fc_k tanh(mdot_k / eps_k) + Fv_k mdot_k
              + tau0_k
(tau_m = T^T tau plus the motor's own rotor inertia J_k and friction, which act on the motor shaft). The rows
are written where the efforts are read: each motor's current noise is its own, so the rows' weights and the
standard errors hold; the joint-side form tau = T^-T (tau_m - J mddot - f) mixes one motor's noise into
every joint it drives, and it shows a motor's friction and rotor inertia in every joint that motor's torque
reaches. A motor whose effort is not logged gives no row. A joint term that is its motor's own column (a
joint driven by one motor: the same function of the same speed) is left to the motor, and a joint's offset
always (the motors' offsets span it). See docs/dynamics_motors.md.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.dynamics.inertial import parameter_names, torque_regressor
from robocal.dynamics.reduced_model import velocity_index
from robocal.dynamics.regression import Regressor, build_regressor, column_values, term_columns
from robocal.dynamics.transmission import Transmission
from robocal.errors import InputError

MOTOR_TERMS = ("coulomb", "viscous", "offset", "armature")
#: joint terms a motor term of the same kind makes redundant
SAME_KIND = {"coulomb": ("coulomb", "coulomb_asymmetric"), "viscous": ("viscous", "viscous_asymmetric"),
             "armature": ("armature",), "offset": ("offset",)}


@dataclass
class Channels:
    """names: one per row of a sample (recorded joints, or logged motors); weights (nc, nv): row c = sum_j
    weights[c, j] x joint j's equation (+ the motor's terms); joint_rows: each channel's velocity index when
    the channels are joints; transmission and motor_terms when they are motors."""

    names: list[str]
    weights: np.ndarray
    joint_rows: list[int] | None = None
    transmission: Transmission | None = None
    motor_terms: tuple[str, ...] = ()
    joint_index: list[int] | None = None          # velocity index of each transmission joint (its row of T)

    @classmethod
    def of_joints(cls, model: pin.Model, recorded: list[str]) -> "Channels":
        rows = [velocity_index(model, j) for j in recorded]
        weights = np.zeros((len(rows), model.nv))
        weights[np.arange(len(rows)), rows] = 1.0
        return cls(list(recorded), weights, rows)

    @classmethod
    def of_motors(cls, model: pin.Model, transmission: Transmission, logged: list[str],
                  motor_terms: tuple[str, ...] = ()) -> "Channels":
        for term in motor_terms:
            if term not in MOTOR_TERMS:
                raise InputError(f"unknown motor term '{term}'; known: {', '.join(MOTOR_TERMS)}",
                                 source=transmission.source, field="model.motor_terms")
        index = [velocity_index(model, j) for j in transmission.joints]
        logged = [m for m in transmission.motors if m in logged]            # the transmission's order
        weights = np.zeros((len(logged), model.nv))
        for c, m in enumerate(logged):
            weights[c, index] = transmission.matrix[:, transmission.motors.index(m)]
        return cls(logged, weights, None, transmission, tuple(motor_terms), index)

    @property
    def motors(self) -> bool:
        return self.transmission is not None

    def term_joints(self) -> list[int]:
        """Velocity indices of the joints whose equations reach a row (model order): their terms are fitted."""
        if self.joint_rows is not None:
            return list(self.joint_rows)
        return [j for j in range(self.weights.shape[1]) if np.any(self.weights[:, j] != 0)]

    def joint_terms(self, model: pin.Model, terms: tuple[str, ...]) -> tuple[dict[int, tuple[str, ...]], list[str]]:
        """({velocity index: terms} for term_joints, notes): `terms` less those the motors' terms hold."""
        out, notes = {}, []
        for j in self.term_joints():
            keep = tuple(terms)
            if self.motors:
                single = np.count_nonzero(self.transmission.matrix[self.joint_index.index(j)]) == 1
                drop = {k for m in self.motor_terms for k in SAME_KIND[m] if single or m == "offset"}
                keep = tuple(t for t in terms if t not in drop)
                if len(keep) < len(terms):
                    dropped = ", ".join(t for t in terms if t in drop)
                    notes.append(f"{model.names[_joint_id(model, j)]}: joint term(s) {dropped} left to the motors' "
                                 "(the same columns on the motors' rows)")
            out[j] = keep
        return out, notes

    def motor_kinematics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, ...]:
        """(m, mdot, mddot) (T, nc) of the channels' motors from model-order joint arrays (T, nv)."""
        tr = self.transmission
        cols = [tr.motors.index(m) for m in self.names]
        m = tr.motor_positions(q[:, self.joint_index])[:, cols]
        return m, tr.motor_rates(v[:, self.joint_index])[:, cols], tr.motor_rates(a[:, self.joint_index])[:, cols]

    def joint_map(self, model: pin.Model) -> tuple[list[str], list[int], np.ndarray]:
        """(joint names, velocity indices, M (nc, k)) of the joints whose torque the channels determine:
        joint torques = channel torques @ M. Without a transmission the recorded joints; with one, tau =
        T^-T tau_m for each joint whose row of T^-T needs only logged motors."""
        if not self.motors:
            return list(self.names), list(self.joint_rows), np.eye(len(self.names))
        tr = self.transmission
        names, idx, cols = [], [], []
        for i, joint in enumerate(tr.joints):
            if set(tr.motors_of_joint_torque(joint)) <= set(self.names):
                names.append(joint)
                idx.append(self.joint_index[i])
                cols.append([tr.inverse[tr.motors.index(m), i] for m in self.names])
        return names, idx, np.array(cols).T.reshape(len(self.names), len(names))


def _joint_id(model: pin.Model, idx_v: int) -> int:
    return next(j for j in range(1, model.njoints) if model.joints[j].idx_v == idx_v)


def channel_regressor(model: pin.Model, q: np.ndarray, v: np.ndarray, a: np.ndarray, channels: Channels,
                      joint_terms: dict[int, tuple[str, ...]], joint_width: np.ndarray, motor_width: np.ndarray,
                      replace: bool = True) -> Regressor:
    """The regressor of the channels' rows (module docstring): inertial columns, then each term joint's term
    columns (joint order), then each motor channel's (channel order). joint_width: the Coulomb tanh width per
    term joint; motor_width per channel. Without a transmission this is regression.build_regressor."""
    if not channels.motors:
        return build_regressor(model, q, v, a, channels.joint_rows, joint_terms, joint_width, replace)
    T, nc = len(q), len(channels.names)
    Y = torque_regressor(model, q, v, a).reshape(T, model.nv, -1)
    rows = np.einsum("cj,tjp->tcp", channels.weights, Y)
    term_joints = channels.term_joints()
    width = np.ones(model.nv)
    width[term_joints] = np.broadcast_to(np.asarray(joint_width, float), (len(term_joints),))
    joint_cols = column_values(_positions(model, q), v, a, width)
    m, md, mdd = channels.motor_kinematics(q, v, a)
    motor_cols = column_values(m, md, mdd, np.broadcast_to(np.asarray(motor_width, float), (nc,)))
    extra, names = [], []
    for j in term_joints:
        for kind in term_columns(joint_terms.get(j, ()), replace):
            extra.append(joint_cols[kind][:, j:j + 1] * channels.weights[:, j])
            names.append(f"{model.names[_joint_id(model, j)]}.{kind}")
    for c, motor in enumerate(channels.names):
        for kind in channels.motor_terms:
            col = np.zeros((T, nc))
            col[:, c] = motor_cols[kind][:, c]
            extra.append(col)
            names.append(f"{motor}.{kind}")
    X = np.concatenate([rows] + [e[:, :, None] for e in extra], axis=2).reshape(T * nc, -1)
    return Regressor(X, parameter_names(model) + names, rows.shape[2], list(range(nc)))


def _positions(model: pin.Model, q: np.ndarray) -> np.ndarray:
    """(T, nv): each one-axis joint's position at its velocity index (the spring's column)."""
    out = np.zeros((len(q), model.nv))
    for j in range(1, model.njoints):
        out[:, model.joints[j].idx_v] = q[:, model.joints[j].idx_q]
    return out
