"""Contact models for the simulator: the wrench the robot exerts on its surroundings.

Each model maps the TCP position x (3,) m and velocity v (3,) m/s (world) to a wrench (6,)
[N, N m] in world-aligned axes at the TCP, robot on environment (spec §11.1 sign). The environment
pushes back with the opposite wrench.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError


def _unit(direction) -> np.ndarray:
    d = np.asarray(direction, float)
    n = np.linalg.norm(d)
    if d.shape != (3,) or not n > 0:
        raise InputError(f"direction must be a non-zero 3-vector, got {direction}", field="direction")
    return d / n


@dataclass
class Wall:
    """Plane through `point` with unit `normal` pointing into the wall; stiffness N/m, damping N s/m
    (only while in contact, and never pulling)."""

    point: np.ndarray
    normal: np.ndarray
    stiffness: float
    damping: float = 0.0

    def __post_init__(self):
        self.point, self.normal = np.asarray(self.point, float), _unit(self.normal)
        if not self.stiffness > 0 or self.damping < 0:
            raise InputError("wall stiffness must be > 0 and damping >= 0", field="stiffness")

    def wrench(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        depth = (x - self.point) @ self.normal
        out = np.zeros(6)
        if depth > 0:
            out[:3] = max(0.0, self.stiffness * depth + self.damping * (v @ self.normal)) * self.normal
        return out


@dataclass
class ViscousLoad:
    """Drag b N s/m along `direction` (a cutting-like load): force b (v . d) d."""

    direction: np.ndarray
    coefficient: float

    def __post_init__(self):
        self.direction = _unit(self.direction)

    def wrench(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        out = np.zeros(6)
        out[:3] = self.coefficient * (v @ self.direction) * self.direction
        return out


@dataclass
class ConstantForce:
    """A fixed force N the robot must exert (an operator or a dead load), world axes."""

    force: np.ndarray

    def wrench(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.r_[np.asarray(self.force, float), 0.0, 0.0, 0.0]


class Environment:
    """Sum of contact models."""

    def __init__(self, *parts):
        self.parts = list(parts)

    def wrench(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        out = np.zeros(6)
        for part in self.parts:
            out += part.wrench(x, v)
        return out
