"""Predicted accuracy of a calibration from its pose set and measurement noise alone (no data).

With unit-variance rows (row / sigma), a linear(ised) least-squares fit of the base parameters has
covariance C = (J^T J)^-1. A frame's pose error at configuration q is then e(q) = G(q) d_theta with
G the frame's parameter Jacobian (LOCAL twist), so cov e(q) = G C G^T. The translation and rotation
blocks are turned to the measurement (world) frame with the pose's rotation R: delta p = R v,
delta phi = R w. The RMS position error at q is sqrt(trace of its 3x3 block) (rotation-invariant).

Parameters that no candidate can separate (dependent in the base selection) are fixed in a
calibration; their effect is regrouped into the base parameters, so leaving them out of G is exact
for the frames whose motion the measurements see.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.design.selection import DesignMatrix, assess, select_poses
from robocal.estimation.identifiability import covariance


@dataclass
class ParameterPrediction:
    """Predicted standard errors of the base parameters (SI units: m, rad)."""

    names: list[str]                 # base parameters (identifiable from the candidates)
    columns: list[int]               # their columns among the free parameters
    covariance: np.ndarray           # (L, L), SI
    stderr: np.ndarray               # (L,)
    unidentifiable: list[str]        # base parameters this pose set leaves undetermined (stderr inf)
    structural: list[str]            # never identifiable from these measurement types (fixed)

    def table(self) -> list[dict]:
        return [{"name": n, "stderr": float(s)} for n, s in zip(self.names, self.stderr)]


def predict_parameters(design: DesignMatrix, chosen, noise_scale: float = 1.0) -> ParameterPrediction:
    """Covariance of the base parameters estimated from the chosen candidates.

    noise_scale multiplies every measurement sigma (1 = the sigmas of the source problem).
    """
    ident = assess(design, chosen)
    cols = list(design.base.independent)
    names = [design.names[j] for j in cols]
    if ident.unidentifiable:
        L = len(cols)
        cov = np.full((L, L), np.inf)
        stderr = np.full(L, np.inf)
    else:
        rows = design.rows_of(chosen)
        Js = design.J[np.ix_(rows, cols)] / design.scale       # scaled columns: better conditioned QR
        cov = covariance(Js, noise_scale ** 2) / np.outer(design.scale, design.scale)
        stderr = np.sqrt(np.diag(cov))
    return ParameterPrediction(names, cols, cov, stderr, ident.unidentifiable, ident.structural)


def pose_jacobians(problem, frame: str, configurations: np.ndarray,
                   directions: np.ndarray | None = None) -> np.ndarray:
    """(V, 6, n_free) world-aligned [delta p; delta phi] of `frame` per free parameter at each configuration.

    problem: anything with model_state() whose samples give pose(frame) and frame_parameter_jacobian(frame),
    with the same free-parameter columns as the DesignMatrix built from it.
    directions: (V, n_read) approach direction of each joint (-1, 0, +1) for backlash parameters; None = 0,
    the centre of the play, where a backlash parameter moves nothing.
    """
    ms = problem.model_state()
    configurations = np.atleast_2d(configurations)
    if directions is not None:
        directions = np.asarray(directions, dtype=float)
        if directions.shape != configurations.shape:
            raise ValueError(f"directions must have the configurations' shape {configurations.shape}, "
                             f"got {directions.shape}")
    out = []
    for i, v in enumerate(configurations):
        s = ms.sample(v, direction=None if directions is None else directions[i])
        G = s.frame_parameter_jacobian(frame)
        R = s.pose(frame).rotation
        out.append(np.vstack([R @ G[:3], R @ G[3:]]))
    return np.array(out).reshape(-1, 6, len(problem.params.free_names))


def position_weight(G: np.ndarray) -> np.ndarray:
    """W = mean over configurations of G_p^T G_p: trace(C W) is the mean squared position error."""
    Gp = G[:, :3]
    return np.einsum("vri,vrj->ij", Gp, Gp) / len(G)


@dataclass
class PosePrediction:
    """Predicted tool accuracy over validation configurations (SI: m, rad; 1-sigma).

    position      (V,) RMS position error sqrt(trace cov p) at each configuration
    orientation   (V,) RMS orientation error sqrt(trace cov phi)
    position_axes (V, 3) standard deviation along the measurement frame's x, y, z
    """

    position: np.ndarray
    orientation: np.ndarray
    position_axes: np.ndarray

    @property
    def mean_position(self) -> float:
        return float(np.mean(self.position))

    @property
    def rms_position(self) -> float:
        """sqrt of the mean squared position error over the configurations."""
        return float(np.sqrt(np.mean(self.position ** 2)))

    @property
    def max_position(self) -> float:
        return float(np.max(self.position))

    @property
    def mean_orientation(self) -> float:
        return float(np.mean(self.orientation))

    @property
    def max_orientation(self) -> float:
        return float(np.max(self.orientation))

    def summary(self) -> dict[str, float]:
        """In report units: mm and mrad."""
        return {"mean_position_mm": 1e3 * self.mean_position, "rms_position_mm": 1e3 * self.rms_position,
                "max_position_mm": 1e3 * self.max_position, "mean_orientation_mrad": 1e3 * self.mean_orientation,
                "max_orientation_mrad": 1e3 * self.max_orientation}


def predict_pose_accuracy(pred: ParameterPrediction, G: np.ndarray) -> PosePrediction:
    """Tool accuracy at each configuration from `pose_jacobians` output and a parameter prediction."""
    Gb = G[:, :, pred.columns]
    if pred.unidentifiable:
        inf = np.full(len(G), np.inf)
        return PosePrediction(inf, inf.copy(), np.full((len(G), 3), np.inf))
    cov = np.einsum("vri,ij,vsj->vrs", Gb, pred.covariance, Gb)     # (V, 6, 6)
    d = np.maximum(np.einsum("vrr->vr", cov), 0.0)
    return PosePrediction(np.sqrt(d[:, :3].sum(1)), np.sqrt(d[:, 3:].sum(1)), np.sqrt(d[:, :3]))


@dataclass
class CurvePoint:
    n: int
    criterion_value: float
    prediction: PosePrediction


def accuracy_curve(design: DesignMatrix, counts, G: np.ndarray, criterion: str = "D", noise_scale: float = 1.0,
                   W: np.ndarray | None = None, greedy: np.ndarray | None = None) -> list[CurvePoint]:
    """Predicted accuracy against the number of poses: a fresh selection for each count in `counts`.
    greedy: `greedy_order(design, max(counts), criterion, W)` when already computed (the same selections)."""
    out = []
    for n in counts:
        sel = select_poses(design, int(n), criterion, W=W, start=None if greedy is None else greedy[:int(n)])
        pp = predict_pose_accuracy(predict_parameters(design, sel.chosen, noise_scale), G)
        out.append(CurvePoint(int(n), sel.value, pp))
    return out
