"""A transmission from motors to joints: joint positions q = T m + c, motor torques tau_m = K i.

T (n x n, rows the joints, columns the motors) holds the gear ratios on its diagonal entries (joint rad per
motor rad: 1 / ratio) and the coupling of a motor that moves several joints off it; c the joint offsets; K the
motors' torque constants (N m/A) when the log holds currents. The map must be square and invertible: every
motor position follows from the joint positions and back.

Torques follow from power: the motors deliver what the joints absorb, tau_m . mdot = tau . qdot for every
motion, and qdot = T mdot, so tau_m = T^T tau and tau = T^-T tau_m. (TIAGo's differential wrist, q6 =
(m7 - m6)/2 + c6, q7 = (m6 + m7)/2 + c7: T = [[-1/2, 1/2], [1/2, 1/2]], T^-T = [[-1, 1], [1, 1]], so tau6 =
e7 - e6 and tau7 = e6 + e7, the relations its controller's log satisfies; docs/dynamics_motors.md.)
Arrays are row-per-sample here: q (N, n) = m @ T^T + c, tau (N, n) = tau_m @ T^-1, tau_m = tau @ T.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError

#: a transmission whose row-scaled matrix has a condition number above this is singular for the fit
SINGULAR_CONDITION = 1e10
EFFORT_KINDS = ("current", "torque")


@dataclass
class Transmission:
    """joints (rows, the config's robot.joints order) and motors (columns); matrix T; offset c (n,) in
    the joints' units; motor_constant (n,) N m/A per motor, None when the efforts are motor torques
    (effort 'torque'). check() refuses what cannot be a transmission."""

    joints: list[str]
    motors: list[str]
    matrix: np.ndarray
    offset: np.ndarray
    motor_constant: np.ndarray | None = None
    source: str = "config"

    def __post_init__(self):
        self.matrix = np.asarray(self.matrix, float)
        self.offset = np.asarray(self.offset, float)
        if self.motor_constant is not None:
            self.motor_constant = np.asarray(self.motor_constant, float)
        self.check()
        self.inverse = np.linalg.inv(self.matrix)

    def check(self) -> None:
        n = len(self.joints)
        if len(self.motors) != n:
            raise InputError(f"{len(self.motors)} motors for {n} joints: the motor-to-joint map must be square "
                             "(one motor per joint)", source=self.source, field="transmission.motors")
        if len(set(self.motors)) != n or set(self.motors) & set(self.joints):
            raise InputError("motor names must be distinct, and differ from the joint names", source=self.source,
                             field="transmission.motors")
        if self.matrix.shape != (n, n) or self.offset.shape != (n,):
            raise InputError(f"the matrix must be {n} x {n} and the offsets {n} values (got {self.matrix.shape}, "
                             f"{self.offset.shape})", source=self.source, field="transmission.matrix")
        if not (np.all(np.isfinite(self.matrix)) and np.all(np.isfinite(self.offset))):
            raise InputError("non-finite entry", source=self.source, field="transmission.matrix")
        if self.motor_constant is not None and (self.motor_constant.shape != (n,)
                                                or np.any(np.isinf(self.motor_constant))):
            raise InputError(f"expected {n} finite torque constants", source=self.source,
                             field="transmission.motor_constant")
        rows = np.abs(self.matrix).max(axis=1)
        empty = [j for j, r in zip(self.joints, rows) if r == 0]
        if empty:
            raise InputError(f"no motor moves joint(s) {', '.join(empty)}: the map is singular", source=self.source,
                             field="transmission.matrix")
        scaled = self.matrix / rows[:, None]           # joint units (rad, m) apart: each row to its largest entry
        if np.linalg.cond(scaled) > SINGULAR_CONDITION:
            _, _, vt = np.linalg.svd(scaled.T)
            weights = vt[-1]                           # rows whose combination vanishes
            involved = [j for j, w in zip(self.joints, weights) if abs(w) > 1e-6 * np.abs(weights).max()]
            raise InputError("the motor-to-joint map is singular: the rows of joints " + ", ".join(involved)
                             + " are linearly dependent (those joints cannot be moved independently by the motors)",
                             source=self.source, field="transmission.matrix")

    # positions and rates
    def joint_positions(self, m: np.ndarray) -> np.ndarray:
        """q (N, n) from motor positions m (N, n)."""
        return np.asarray(m, float) @ self.matrix.T + self.offset

    def motor_positions(self, q: np.ndarray) -> np.ndarray:
        return (np.asarray(q, float) - self.offset) @ self.inverse.T

    def motor_rates(self, qdot: np.ndarray) -> np.ndarray:
        """Motor velocities (or accelerations) from joint ones: mdot = T^-1 qdot."""
        return np.asarray(qdot, float) @ self.inverse.T

    # torques
    def motor_torques(self, effort: np.ndarray, motors: list[str] | None = None) -> np.ndarray:
        """Motor torques (N, k) of the logged motors `motors` (default all) from their efforts: K i for currents."""
        if self.motor_constant is None:
            return np.asarray(effort, float)
        idx = [self.motors.index(m) for m in (motors or self.motors)]
        return np.asarray(effort, float) * self.motor_constant[idx]

    def joint_torques(self, tau_m: np.ndarray) -> np.ndarray:
        """tau = T^-T tau_m (every motor's torque needed)."""
        return np.asarray(tau_m, float) @ self.inverse

    def motors_of_joint_torque(self, joint: str) -> list[str]:
        """The motors whose torque a joint's torque is made of (nonzero entries of its row of T^-T)."""
        row = self.inverse[:, self.joints.index(joint)]
        return [m for m, w in zip(self.motors, row) if abs(w) > 1e-12 * np.abs(row).max()]

    def to_dict(self) -> dict:
        return {"joints": list(self.joints), "motors": list(self.motors),
                "matrix": {j: {m: float(v) for m, v in zip(self.motors, row) if v != 0}
                           for j, row in zip(self.joints, self.matrix)},
                "offset": {j: float(c) for j, c in zip(self.joints, self.offset) if c != 0},
                "effort": "torque" if self.motor_constant is None else "current",
                **({} if self.motor_constant is None else
                   {"motor_constant": {m: float(k) for m, k in zip(self.motors, self.motor_constant)
                                       if np.isfinite(k)}})}

    @classmethod
    def from_dict(cls, d: dict, source: str) -> "Transmission":
        """The side file's form (to_dict): a named matrix, offsets and constants."""
        joints, motors = list(d["joints"]), list(d["motors"])
        matrix = np.array([[float(d["matrix"].get(j, {}).get(m, 0.0)) for m in motors] for j in joints])
        offset = np.array([float(d.get("offset", {}).get(j, 0.0)) for j in joints])
        constants = None if d.get("effort", "current") == "torque" else np.array(
            [float(d["motor_constant"].get(m, np.nan)) for m in motors])
        return cls(joints, motors, matrix, offset, constants, source)
