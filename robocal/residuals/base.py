"""The residual interface: a measurement type knows frames and points, never model parameters.

For each of its terms a residual returns the prediction error (prediction - measurement, SI units),
its derivative with respect to a LOCAL right twist of every frame it looks at (M <- M exp6(xi)), and
its derivative with respect to its own set-up quantities ("auxiliary" parameters: a plane, a sphere
centre, a ball-bar offset). Known set-up quantities are auxiliary parameters with vary=False, so the
same code serves the known and the unknown case. The problem layer turns frame twists into parameter
columns; see robocal.model.kinematics.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from functools import lru_cache
from typing import ClassVar, Sequence

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.model import lie_arrays
from robocal.model.lie_arrays import skew
from robocal.model.parameters import Parameter


@dataclass
class Term:
    """One term: r (d,), frames [(sample index, frame name, dr/dxi (d, 6))], aux (d, n_aux) or None."""

    r: np.ndarray
    frames: list[tuple[int, str, np.ndarray]] = field(default_factory=list)
    aux: np.ndarray | None = None


@dataclass
class BatchTerms:
    """Every term of a residual at once (n terms): r (n, d), D (n, d, 6) the derivative w.r.t. a LOCAL
    right twist of the residual's frame, aux (n, d, n_aux) or None."""

    r: np.ndarray
    D: np.ndarray
    aux: np.ndarray | None = None


@dataclass
class Aux:
    """A set-up quantity of a residual: suffix of its parameter name, initial value, unit, vary."""

    suffix: str
    value: float
    unit: str
    vary: bool


class Residual(ABC):
    """Base class of every measurement type. Subclasses live in one small file each.

    name        prefix of the residual's auxiliary parameter names and label in reports
    samples     (n_terms,) sample index of each term (a term uses one sample unless a subclass says otherwise)
    sigma       (dim,) standard deviation of each row, SI units
    weights     (dim,) per-row weights; 0 means "not measured" and drops that row
    measurements (n_terms, len(columns)) raw measured values (empty for pure constraint types)
    term_scale  (n_terms,) or None: a per-term multiplier of the row scale (a per-term sigma: sigma / term_scale,
                as a camera's per-corner pixel sigma)
    """

    type_name: ClassVar[str] = ""
    #: True when the data hold a measured quantity (simulate by prediction + noise); False for
    #: contact-type constraints whose only data are joint readings (simulate by moving the robot onto them).
    observed: ClassVar[bool] = True
    #: robot frames whose placement this measurement registers, as it registers its own set-up (a camera's
    #: hand-eye transform): identifiability orders their placement before the joints (estimation.problem)
    registration_frames: tuple[str, ...] = ()

    def __init__(self, name: str, samples, sigma, weights=None):
        self.name = name
        self.samples = np.asarray(samples, dtype=int).reshape(-1)
        sig = np.broadcast_to(np.asarray(sigma, dtype=float), (self.dim,)).copy()
        if not np.all(np.isfinite(sig) & (sig > 0)):
            raise InputError(f"residual '{name}': sigma must be positive and finite, got {sig.tolist()}",
                             field="sigma")
        self.sigma = sig
        self.weights = np.ones(self.dim) if weights is None else np.broadcast_to(
            np.asarray(weights, dtype=float), (self.dim,)).copy()
        if not np.all(np.isfinite(self.weights) & (self.weights >= 0)) or not np.any(self.weights):
            # a weight scales a row's information: negative has no meaning, 0 drops the row (not all of them)
            raise InputError(f"residual '{name}': weights must be finite, positive or 0 (0 drops a row) and not "
                             f"all 0, got {self.weights.tolist()}", field="weights")
        self.aux: list[Aux] = []
        self.columns: list[str] = []
        self.measurements = np.zeros((len(self.samples), 0))
        self.term_scale: np.ndarray | None = None

    # ---- what subclasses define --------------------------------------------------------
    @property
    @abstractmethod
    def dim(self) -> int:
        """Rows per term."""

    @property
    @abstractmethod
    def row_units(self) -> tuple[str, ...]:
        """'length' or 'angle' for each row (for reports in mm and mrad)."""

    @abstractmethod
    def evaluate(self, k: int, states: Sequence, aux: np.ndarray) -> Term:
        """Error and derivatives of term k. states[i] is the SampleState of sample i."""

    def evaluate_batch(self, terms: slice, R: np.ndarray, p: np.ndarray, aux: np.ndarray) -> BatchTerms:
        """Terms `terms` (a slice) at once, from the frame's world poses at their samples, R (n, 3, 3), p (n, 3).

        Optional: types with one frame and one sample per term define it to serve the batched evaluation
        (robocal.estimation.problem); it must agree with `evaluate` term by term."""
        raise NotImplementedError(f"{self.type_name} has no batched evaluation")

    @property
    def batched(self) -> bool:
        """Whether `evaluate_batch` serves this residual: defined, and `evaluate` not overridden below it
        (a subclass that changes `evaluate` alone falls back to the per-term path)."""
        return batch_capable(type(self))

    def simulate(self, k: int, states: Sequence, aux: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A noisy measurement row for term k (observed types only)."""
        raise NotImplementedError(f"{self.type_name} is a constraint type: simulate by projection")

    @classmethod
    def column_kinds(cls, n_columns: int) -> list[str]:
        """Kind of each measurement column ('length', 'angle' or '' for unitless) for unit handling."""
        return ["length"] * n_columns

    # ---- shared -------------------------------------------------------------------------
    @property
    def n_terms(self) -> int:
        return len(self.samples)

    def term_samples(self, k: int) -> tuple[int, ...]:
        return (int(self.samples[k]),)

    def placed_per_session(self) -> list[str]:
        """Set-up parameters of this block that place something fixed in the world (a camera's target or camera):
        a session that re-places the robot's surroundings re-registers them with base.* (cross_validation)."""
        return []

    def term_feature(self, k: int) -> tuple:
        """What term k measures beside its posture, when one posture gives several terms (a camera image: one
        term per corner); terms of equal postures and features repeat each other (workflows/posture_check.py)."""
        return ()

    def aux_parameters(self) -> list[Parameter]:
        return [Parameter(f"{self.name}.{a.suffix}", "auxiliary", self.name, i, value=a.value, vary=a.vary,
                          unit=a.unit) for i, a in enumerate(self.aux)]

    def aux_scales(self) -> dict[str, tuple[float, float]]:
        """{auxiliary parameter name: (physical scale, standard error below which it is determined)} for set-up
        quantities that have a physical scale (a camera's intrinsics); the others have none."""
        return {}

    def machine_parameter_names(self) -> list[str]:
        """Unknowns of this residual that are the machine's geometry (a parallel CMM's error parameters), not a
        measurement set-up: never fitted when the nominal model is registered for the "before" figures."""
        return []

    def row_scale(self) -> np.ndarray:
        """Multiplier that turns a row of r into a unit-variance row (0 drops it)."""
        return self.weights / self.sigma

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, terms={self.n_terms})"


@lru_cache(maxsize=None)
def batch_capable(cls: type) -> bool:
    owner = next((c for c in cls.__mro__ if "evaluate_batch" in vars(c)), Residual)
    return owner is not Residual and cls.evaluate is owner.evaluate


# ---- geometry helpers shared by residual files ---------------------------------------------
def point_jacobian(M: pin.SE3, p_local: np.ndarray) -> np.ndarray:
    """(3, 6) derivative of the world point M * p_local w.r.t. a LOCAL right twist of M."""
    R = M.rotation
    return np.hstack([R, -R @ skew(p_local)])


def basis_from_normal(n: np.ndarray) -> np.ndarray:
    """A rotation whose third column is the unit vector n (deterministic choice of the other two)."""
    n = np.asarray(n, dtype=float)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(helper, n)
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(n, e1), n])


def tilted_direction(R0: np.ndarray, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit direction R0 [a, b, 1]/|.| (two-parameter tilt of R0's z axis) and its (3, 2) derivative."""
    w = np.array([a, b, 1.0])
    s = np.linalg.norm(w)
    u = w / s
    dw = (np.eye(3)[:, :2] - np.outer(u, u[:2])) / s   # d(w/|w|)/d(a, b)
    return R0 @ u, R0 @ dw


def vector_aux(prefix: str, value, unit: str, vary: bool) -> list[Aux]:
    value = np.asarray(value, dtype=float).reshape(3)
    return [Aux(f"{prefix}.{c}", float(v), unit, vary) for c, v in zip("xyz", value)]


def distance_terms(R: np.ndarray, p: np.ndarray, aux: np.ndarray, length) -> BatchTerms:
    """Batched r = |M tip - centre| - length - aux[3], aux = [centre (3), length correction, tip (3)]: a ball on
    the frame at a distance from a fixed centre (sphere contact, ball bar)."""
    w = lie_arrays.act(R, p, aux[4:7]) - aux[:3]
    dist = np.linalg.norm(w, axis=1)
    e = w / dist[:, None]
    r = (dist - length - aux[3])[:, None]
    A = np.concatenate([-e, -np.ones((len(e), 1)), np.einsum("ni,nij->nj", e, R)], axis=1)[:, None, :]
    D = np.einsum("ni,nij->nj", e, lie_arrays.point_jacobian(R, aux[4:7]))[:, None, :]
    return BatchTerms(r, D, A)
