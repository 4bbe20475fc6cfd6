"""The identified model as files a user can load: the URDF (inertias; viscous and Coulomb friction in
<dynamics damping friction>) and a side file, dynamics.yaml, with everything URDF has no element for.

The side file holds, per recorded joint, every extra term's value (coulomb, viscous - repeated from the
URDF -, offset, armature, spring, coulomb_pos/neg, viscous_pos/neg), the Coulomb tanh width, the delay of
the torque reading behind the motion, the map from logged efforts to torques (effort_map.py) and the signal
processing a new log must go through to be predicted the same way (cut-off, order, velocity source, edge
trim). `predict_torques` is the model: Pinocchio's RNEA on the URDF (rotor inertias set as
model.armature, which RNEA adds as armature x acceleration) plus the other terms; robocal reads the side
file back with `read_side_file`. (Motor-side terms, issue 38, add a per-motor section here.)
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robocal.dynamics.effort_map import EffortMap
from robocal.dynamics.reduced_model import velocity_index
from robocal.dynamics.regression import column_values
from robocal.errors import InputError

SIDE_FILE = "dynamics.yaml"
FORMAT = "robocal identified dynamics 1"


@dataclass
class IdentifiedDynamics:
    """urdf: the identified URDF's file name (beside the side file); joints: the model's free joints (the
    others locked at neutral); effort: the efforts-to-torques map; terms: {joint: {column kind: value}};
    coulomb_width, delay_s: {joint: value}; signal: {cutoff_hz, order, velocity_source, edge_periods}."""

    urdf: str
    joints: list[str]
    effort: EffortMap
    terms: dict[str, dict[str, float]]
    coulomb_width: dict[str, float]
    delay_s: dict[str, float]
    signal: dict = field(default_factory=dict)

    @property
    def recorded(self) -> list[str]:
        return self.effort.recorded

    def to_dict(self) -> dict:
        return {"format": FORMAT, "urdf": self.urdf, "joints": list(self.joints), "effort": self.effort.to_dict(),
                "terms": self.terms, "coulomb_width": self.coulomb_width, "delay_s": self.delay_s,
                "signal": self.signal}

    @classmethod
    def from_dict(cls, d: dict, source: str) -> "IdentifiedDynamics":
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise InputError(f"not a robocal identified-dynamics file (format '{FORMAT}' expected)", source=source,
                             field="format")
        try:
            return cls(str(d["urdf"]), list(d["joints"]), EffortMap.from_dict(d["effort"]),
                       {j: {k: float(v) for k, v in t.items()} for j, t in d["terms"].items()},
                       {j: float(v) for j, v in d["coulomb_width"].items()},
                       {j: float(v) for j, v in d["delay_s"].items()}, dict(d.get("signal", {})))
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
    """(T, nr) torques of the recorded joints at the same instants as q, v, a (T, nq / nv), without the
    delay (the reading at t + delay_s is this torque at t). `model` must carry the rotor inertias
    (IdentifiedDynamics.with_armature)."""
    data = model.createData()
    idx = [velocity_index(model, j) for j in dyn.recorded]
    tau = np.array([pin.rnea(model, data, q[k], v[k], a[k])[idx] for k in range(len(q))])
    for c, joint in enumerate(dyn.recorded):
        j = idx[c]
        q_j = q[:, model.joints[model.getJointId(joint)].idx_q]
        cols = column_values(q_j, v[:, j], a[:, j], dyn.coulomb_width.get(joint, 1.0))
        for kind, value in dyn.terms.get(joint, {}).items():
            if kind != "armature":
                tau[:, c] += value * cols[kind]
    return tau
