"""Findings: robot parameters the data determine firmly, far from their nominal value.

A finding is written to the URDF and reported with what to check on the robot; it is never a reason to refuse
the fit.

The rule (docs/validation.md argues k and m), with d = |value - nominal|, s its physical scale
(robocal.estimation.physical_scale) and se its data-only standard error (robocal.estimation.determinacy):

    finding  when  d > FINDING_SCALES x s   and   se < d / FINDING_SIGMAS      (k = 3, m = 4)

A parameter beyond BEYOND scales that misses the second condition is not determined by the data: that one is
refused (robocal.estimation.plausibility), with the change that fixes it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.estimation.physical_scale import FINDING_SCALES, FINDING_SIGMAS, unit_label

CHECK = {       # what to look at on the robot, per parameter kind
    "joint_offset": "the joint's encoder zero / homing (reference mark, zero offset in the controller)",
    "joint_placement": "the link's machining, or a mounting error where the joint's housing is fixed to its "
                       "parent link",
    "frame_placement": "the frame's mounting (tool, sensor or bracket)",
    "joint_compliance": "the joint's stiffness: a loose gear or coupling, a soft gearbox, or a wrong gravity "
                        "torque (the URDF's link masses)",
    "joint_backlash": "the gearbox's play",
    "joint_tilt": "the joint's bearing play, or the stiffness of its housing or mount",
    "transmission": "the screw's lead or the coupling's ratio against its datasheet",
}


@dataclass
class Finding:
    name: str
    kind: str
    unit: str
    value: float
    nominal: float
    stderr: float              # the fit's standard error (with the prior's contribution, if any)
    stderr_data: float         # the data's alone
    scale: float
    basis: str                 # what the scale was derived from (load kinds), else ""

    @property
    def in_scales(self) -> float:
        return abs(self.value - self.nominal) / self.scale

    @property
    def in_stderrs(self) -> float:
        return abs(self.value - self.nominal) / self.stderr_data if self.stderr_data > 0 else float("inf")

    @property
    def check(self) -> str:
        return CHECK.get(self.kind, "the robot against its URDF")

    def describe(self) -> str:
        k, u = unit_label(self.unit)
        basis = f"; {self.basis}" if self.basis else ""
        return (f"{self.name} = {k * self.value:+.4g} {u} +- {k * self.stderr:.3g} (data alone +- "
                f"{k * self.stderr_data:.3g}), nominal {k * self.nominal:+.4g}: {self.in_scales:.3g} physical scales "
                f"(scale {k * self.scale:.3g} {u}{basis}), {self.in_stderrs:.3g} standard errors from nominal. "
                f"Check {self.check}")

    def to_dict(self) -> dict:
        return {"parameter": self.name, "kind": self.kind, "unit": self.unit, "value": self.value,
                "nominal": self.nominal, "stderr": self.stderr, "stderr_data_only": self.stderr_data,
                "physical_scale": self.scale, "scale_basis": self.basis, "in_physical_scales": self.in_scales,
                "in_standard_errors": self.in_stderrs, "check": self.check}


def firmly_determined(deviation: float, stderr_data: float | None) -> bool:
    """The data put the parameter FINDING_SIGMAS of its data-only standard errors away from nominal."""
    return stderr_data is not None and np.isfinite(stderr_data) and stderr_data < abs(deviation) / FINDING_SIGMAS


def find(params, nominal: dict[str, float], scales, data_stderr: dict[str, float]) -> list[Finding]:
    """The findings of a fit, largest (in physical scales) first."""
    out = []
    for n, s in scales.scale.items():
        p = params[n] if n in params else None
        if p is None or not p.vary:
            continue
        d = p.value - nominal.get(n, 0.0)
        se = data_stderr.get(n)
        if abs(d) > FINDING_SCALES * s and firmly_determined(d, se):
            out.append(Finding(n, p.kind, p.unit, float(p.value), nominal.get(n, 0.0),
                               float(p.stderr) if p.stderr is not None else float("nan"), float(se), s,
                               scales.basis.get(n, "")))
    return sorted(out, key=lambda f: -f.in_scales)
