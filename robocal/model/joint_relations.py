"""Joint relations of a closed chain: linear rows that tie joint values to each other and to readings.

Each relation is one constraint row, solved together with the loop closures by `loops.assemble`:

* ScrewTransmission (robocal's ``<screw_transmission>``, written by mechanisms/floating_nut_urdf):
  a ball screw whose nut may roll with the joints around it. The stroke joint is listed in
  ``<actuated>``; its reading u is the motor's command length relative to home, which the controller
  converts from the encoder angle with the nominal lead L0 (u = L0/2pi * psi / gear). With the true
  lead L and thread-hand sign sigma the nut travels

      q_stroke + sigma * L / (2 pi) * q_roll - (L / L0) * u = 0

  so the stroke joint is *driven*: assembly solves it, it does not take the reading itself.
* Coupling (URDF+ ``<coupling>``): q_successor - ratio * q_predecessor = 0 (a gear or screw).

Calibration parameters of kind "transmission" (`<name>.lead`, `<name>.hand`, `<name>.ratio`) set the row
coefficients; `derivative` gives the row's change per unit parameter. The hand is discrete (+-1): it is
never varied continuously; choose it by comparing fits (see floating_nut_calibration.choose_thread_hands).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class ScrewTransmission:
    name: str
    stroke_joint: str
    roll_joint: str
    lead: float              # m per revolution of the nut relative to the screw (true value)
    sigma: int               # +-1: thread hand and nut side
    nominal_lead: float      # the lead the controller converts the encoder with
    gear_ratio: float = 1.0

    kind = "screw"
    components = ("lead", "hand")

    @property
    def joints(self) -> tuple[str, str]:
        return self.stroke_joint, self.roll_joint

    @property
    def driven(self) -> str:
        return self.stroke_joint

    def coefficients(self) -> tuple[float, float]:
        return 1.0, self.sigma * self.lead / TWO_PI

    @property
    def reading_scale(self) -> float:
        return self.lead / self.nominal_lead

    def value(self, component: str) -> float:
        return {"lead": self.lead, "hand": float(self.sigma)}[component]

    def with_value(self, component: str, value: float) -> "ScrewTransmission":
        if component == "lead":
            return replace(self, lead=float(value))
        if value not in (-1.0, 1.0):
            raise ValueError(f"{self.name}.hand must be +1 or -1, got {value}")
        return replace(self, sigma=int(value))

    def derivative(self, component: str, joint_values, reading: float) -> float:
        """d row / d component at the joint values (q_stroke, q_roll) and the reading u."""
        if component != "lead":
            raise ValueError(f"{self.name}.{component} is discrete: fix it (vary: false) and compare fits")
        return self.sigma * joint_values[1] / TWO_PI - reading / self.nominal_lead


@dataclass(frozen=True)
class Coupling:
    """A URDF+ coupling: velocity of `successor_joint` = ratio * velocity of `predecessor_joint`."""

    name: str
    predecessor_joint: str
    successor_joint: str
    ratio: float

    kind = "coupling"
    components = ("ratio",)
    driven = None
    reading_scale = 0.0

    @property
    def joints(self) -> tuple[str, str]:
        return self.successor_joint, self.predecessor_joint

    def coefficients(self) -> tuple[float, float]:
        return 1.0, -self.ratio

    def value(self, component: str) -> float:
        return self.ratio

    def with_value(self, component: str, value: float) -> "Coupling":
        return replace(self, ratio=float(value))

    def derivative(self, component: str, joint_values, reading: float) -> float:
        return -joint_values[1]
