"""Held-out scores of identified models: torque RMSE per recorded joint against the filtered and the logged
torque, and the free-motion external force the models leave unexplained (identify_log.py)."""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.dynamics.external_force import ExternalForceEstimator
from robocal.dynamics.regression import Regressor
from robocal.dynamics.wrench import WrenchMapper
from robocal.errors import InputError


def validate(predict: dict, reg: Regressor, measured: np.ndarray, logged: np.ndarray) -> tuple[dict, list, dict]:
    """({model: {'rmse', 'percent_of_range', 'rmse_against_logged'}}, per-joint torque range of `measured`,
    curves {'measured', 'logged', model: prediction}). predict: {model: function of a regressor}."""
    t_range = (measured.max(axis=0) - measured.min(axis=0)).tolist()
    validation, curves = {}, {"measured": measured, "logged": logged}
    for name, f in predict.items():
        pred = f(reg)
        rmse = np.sqrt(np.mean((pred - measured) ** 2, axis=0))
        validation[name] = {"rmse": rmse.tolist(), "percent_of_range": (100 * rmse / np.array(t_range)).tolist(),
                            "rmse_against_logged": np.sqrt(np.mean((pred - logged) ** 2, axis=0)).tolist()}
        curves[name] = pred
    return validation, t_range, curves


def wrench_rms(frame: str | None, source: str, model: pin.Model, q: np.ndarray, rec_idx: list[int],
               predictions: dict, measured: np.ndarray) -> dict:
    """RMS (N) per world axis of the force at `frame` (default: the model's last frame) that explains the
    torque the model misses (measured - predicted, recorded joints only; force only: the recorded joints
    are too few to resolve a moment as well)."""
    name = frame or model.frames[-1].name
    if not model.existFrame(name):
        raise InputError(f"frame '{name}' is not in the model", source=source, field="wrench.frame")
    est = ExternalForceEstimator(model, model.getFrameId(name))
    J = est.jacobians(q)[:, :, rec_idx]
    mapper = WrenchMapper(force_only=True)
    return {k: np.sqrt(np.mean(mapper.map(J, measured - pred).force ** 2, axis=0)).tolist()
            for k, pred in predictions.items()} | {"frame": name}
