"""The identified model as files a user can load: the URDF (inertias; viscous and Coulomb friction in
<dynamics damping friction>) and a side file, dynamics.yaml, with everything URDF has no element for.

The side file holds, per recorded joint, every extra term's value (coulomb, viscous - repeated from the
URDF -, offset, armature, spring, coulomb_pos/neg, viscous_pos/neg), the Coulomb tanh width, the delay of
the torque reading behind the motion, the map from logged efforts to torques (effort_map.py) and the signal
processing a new log must go through to be predicted the same way (cut-off, order, velocity source, edge
trim). `predict_torques` is the model: Pinocchio's RNEA on the URDF (rotor inertias set as
model.armature, which RNEA adds as armature x acceleration) plus the other terms; robocal reads the side
file back with `read_side_file`. A model identified from motor-side logs adds the transmission
(transmission.py: its matrix, offsets, torque constants) and each logged motor's terms (`motor_terms`:
rotor inertia, Coulomb and viscous friction, offset, on the motor shaft); its predictions are the motors'
torques, tau_m = T^T tau + the motor's terms (channels.py). See docs/dynamics_motors.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robocal.dynamics.channels import Channels
from robocal.dynamics.effort_map import EffortMap
from robocal.dynamics.reduced_model import velocity_index
from robocal.dynamics.regression import column_values
from robocal.dynamics.transmission import Transmission
from robocal.errors import InputError

SIDE_FILE = "dynamics.yaml"
FORMAT = "robocal identified dynamics 1"


@dataclass
class IdentifiedDynamics:
    """urdf: the identified URDF's file name (beside the side file); joints: the model's free joints (the
    others locked at neutral); effort: the efforts-to-torques map of the channels (recorded joints, or logged
    motors); terms: {joint: {column kind: value}}; coulomb_width: {joint or motor: value}; delay_s: {channel:
    value}; signal: {cutoff_hz, order, velocity_source, edge_periods, max_rate_hz}; transmission and
    motor_terms {motor: {kind: value}} for a model of motor-side logs."""

    urdf: str
    joints: list[str]
    effort: EffortMap
    terms: dict[str, dict[str, float]]
    coulomb_width: dict[str, float]
    delay_s: dict[str, float]
    signal: dict = field(default_factory=dict)
    transmission: Transmission | None = None
    motor_terms: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def recorded(self) -> list[str]:
        return self.effort.recorded

    def channels(self, model: pin.Model) -> Channels:
        if self.transmission is None:
            return Channels.of_joints(model, self.recorded)
        kinds = tuple(dict.fromkeys(k for t in self.motor_terms.values() for k in t))
        return Channels.of_motors(model, self.transmission, self.recorded, kinds)

    def to_dict(self) -> dict:
        out = {"format": FORMAT, "urdf": self.urdf, "joints": list(self.joints), "effort": self.effort.to_dict(),
               "terms": self.terms, "coulomb_width": self.coulomb_width, "delay_s": self.delay_s,
               "signal": self.signal}
        if self.transmission is not None:
            out |= {"transmission": self.transmission.to_dict(), "motor_terms": self.motor_terms}
        return out

    @classmethod
    def from_dict(cls, d: dict, source: str) -> "IdentifiedDynamics":
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise InputError(f"not a robocal identified-dynamics file (format '{FORMAT}' expected)", source=source,
                             field="format")
        try:
            tr = d.get("transmission")
            return cls(str(d["urdf"]), list(d["joints"]), EffortMap.from_dict(d["effort"]),
                       {j: {k: float(v) for k, v in t.items()} for j, t in d["terms"].items()},
                       {j: float(v) for j, v in d["coulomb_width"].items()},
                       {j: float(v) for j, v in d["delay_s"].items()}, dict(d.get("signal", {})),
                       None if tr is None else Transmission.from_dict(tr, source),
                       {m: {k: float(v) for k, v in t.items()} for m, t in d.get("motor_terms", {}).items()})
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed side file ({exc})", source=source, field=str(exc)) from None

    def with_armature(self, model: pin.Model) -> pin.Model:
        """`model` (the URDF's reduced model) with the rotor inertias of the side file."""
        out = model.copy()
        for joint, terms in self.terms.items():
            out.armature[velocity_index(out, joint)] = terms.get("armature", 0.0)
        return out


def predict_torques(model: pin.Model, dyn: IdentifiedDynamics, q: np.ndarray, v: np.ndarray,
                    a: np.ndarray) -> np.ndarray:
    """(T, nr) torques of the channels (recorded joints, or logged motors) at the same instants as q, v, a (T,
    nq / nv), without the delay (the reading at t + delay_s is this torque at t). `model` must carry the rotor
    inertias (IdentifiedDynamics.with_armature)."""
    data = model.createData()
    full = np.array([pin.rnea(model, data, q[k], v[k], a[k]) for k in range(len(q))]).reshape(len(q), model.nv)
    for joint, terms in dyn.terms.items():
        j = velocity_index(model, joint)
        q_j = q[:, model.joints[model.getJointId(joint)].idx_q]
        cols = column_values(q_j, v[:, j], a[:, j], dyn.coulomb_width.get(joint, 1.0))
        for kind, value in terms.items():
            if kind != "armature":
                full[:, j] += value * cols[kind]
    channels = dyn.channels(model)
    if not channels.motors:
        return full[:, channels.joint_rows]
    tau = full @ channels.weights.T
    m, md, mdd = channels.motor_kinematics(q, v, a)
    for c, motor in enumerate(channels.names):
        cols = column_values(m[:, c], md[:, c], mdd[:, c], dyn.coulomb_width.get(motor, 1.0))
        for kind, value in dyn.motor_terms.get(motor, {}).items():
            tau[:, c] += value * cols[kind]
    return tau
