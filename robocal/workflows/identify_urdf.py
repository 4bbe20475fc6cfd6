"""The identified model as files: the URDF with the consistent inertias and friction (urdf_inertials.py) and
the side file with every other term (identified_model.py), from an IdentifyResult. See docs/dynamics_tiago.md.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from robocal.dynamics.filtering import SignalOptions
from robocal.dynamics.identified_model import IdentifiedDynamics
from robocal.dynamics.identify_log import IdentifyResult
from robocal.dynamics.inertial import parameter_vector
from robocal.dynamics.urdf_inertials import identified_urdf
from robocal.workflows.identify import effort_map_of


def torque_units(res: IdentifyResult) -> list[str]:
    """Per channel: N for a prismatic recorded joint, N m for a revolute one or a motor."""
    return [joint_unit(res.model, j) for j in res.recorded]


def joint_unit(model, name: str) -> str:
    """N for a prismatic joint, N m for a revolute one or a motor (a name that is no joint)."""
    if not model.existJointName(name):
        return "N m"
    return "N" if model.joints[model.getJointId(name)].shortname().startswith("JointModelP") else "N m"


def urdf_of(res: IdentifyResult) -> tuple[str, bytes | None, list[str]]:
    """(file name, URDF bytes or None, remarks or why not): the input URDF carrying the consistent model's
    inertias (urdf_inertials.py); none when the solver stopped short."""
    name = f"{Path(res.config.urdf).stem}_identified.urdf"
    if not res.consistent.converged:
        return name, None, [f"the consistent fit's solver stopped short (status {res.consistent.status})"]
    friction: dict[str, dict[str, float]] = {}
    for joint, terms in joint_term_values(res).items():
        # URDF's <dynamics damping friction> holds one value each: an asymmetric pair's mean (the side file
        # has both)
        for kind in ("viscous", "coulomb"):
            pair = [terms[f"{kind}_pos"], terms[f"{kind}_neg"]] if f"{kind}_pos" in terms else None
            if kind in terms or pair:
                friction.setdefault(joint, {})[kind] = terms[kind] if kind in terms else float(np.mean(pair))
    data, reasons = identified_urdf(Path(res.config.urdf).read_text(encoding="utf-8"), res.model,
                                    res.consistent.inertial, parameter_vector(res.model), friction)
    return name, data, reasons


def joint_term_values(res: IdentifyResult, motors: bool = False) -> dict[str, dict[str, float]]:
    """{joint: {column kind: consistent value}} for the joints with terms, or with motors=True {motor: ...} for
    the logged motors of a motor-side identification."""
    if motors:
        owners = list(res.recorded) if res.channels is not None and res.channels.motors else []
    else:
        owners = list(res.joint_terms)
    out: dict[str, dict[str, float]] = {j: {} for j in owners}
    for value, name in zip(res.consistent.extra, res.consistent_extra_names()):
        owner, kind = name.rsplit(".", 1)
        if owner in out:
            out[owner][kind] = float(value)
    return out


def side_file(res: IdentifyResult, urdf_name: str) -> IdentifiedDynamics:
    """What URDF cannot hold (identified_model.py), for `robocal evaluate` and any reader."""
    cfg, proc = res.config, res.processed
    motor_side = res.channels is not None and res.channels.motors
    widths = dict(zip(res.joint_terms, res.coulomb_width.tolist())) | (
        dict(zip(res.recorded, res.motor_width.tolist())) if motor_side else {})
    signal = {"cutoff_hz": float(proc.cutoff_hz), "order": int(proc.order), "velocity_source": proc.velocity_source,
              "edge_periods": float(cfg.signal.edge_periods)}
    if motor_side or cfg.signal.max_rate_hz != SignalOptions.max_rate_hz:
        signal["max_rate_hz"] = float(cfg.signal.max_rate_hz)
    return IdentifiedDynamics(
        urdf_name, list(cfg.joints), effort_map_of(cfg, res.recorded), joint_term_values(res),
        {j: float(w) for j, w in widths.items()}, {j: float(d) for j, d in zip(res.recorded, res.delays)}, signal,
        res.channels.transmission if motor_side else None, joint_term_values(res, motors=True))


def identified_urdf_entry(urdf: tuple) -> dict:
    name, data, reasons = urdf
    return {"file": name if data is not None else None, "not_written_because": [] if data is not None else reasons,
            "remarks": reasons if data is not None else []}
