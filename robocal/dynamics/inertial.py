"""Inertial parameters of a Pinocchio model: names, vectors, regressors, physical consistency.

Per body, 10 parameters about the joint origin in joint axes (Pinocchio's toDynamicParameters):
[m, mc_x, mc_y, mc_z, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] (kg, kg m, kg m^2).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.errors import InputError

TERMS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def parameter_names(model: pin.Model) -> list[str]:
    return [f"{model.names[j]}.{t}" for j in range(1, model.njoints) for t in TERMS]


def parameter_vector(model: pin.Model) -> np.ndarray:
    """(10 (njoints - 1),) the model's inertial parameters."""
    return np.concatenate([model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)])


def with_parameters(model: pin.Model, params: np.ndarray) -> pin.Model:
    """A copy of the model carrying `params` (any values: consistency is not required here)."""
    p = np.asarray(params, float).reshape(model.njoints - 1, 10)
    out = model.copy()
    for j in range(1, model.njoints):
        out.inertias[j] = pin.Inertia.FromDynamicParameters(p[j - 1])
    return out


def torque_regressor(model: pin.Model, q: np.ndarray, v: np.ndarray, a: np.ndarray, rows=None) -> np.ndarray:
    """Stacked joint-torque regressor (T nv, 10 (njoints - 1)), rows sample-major: tau = Y @ pi. rows: the
    velocity indices kept (T len(rows) rows), every one by default; written into one array as computed."""
    q, v, a = (np.atleast_2d(np.asarray(x, float)) for x in (q, v, a))
    if not (len(q) == len(v) == len(a)):
        raise InputError("q, v, a must have the same number of samples", field="q")
    data = model.createData()
    keep = slice(None) if rows is None else np.asarray(rows, int)
    out = np.empty((len(q), model.nv if rows is None else len(keep), 10 * (model.njoints - 1)))
    for k in range(len(q)):
        out[k] = pin.computeJointTorqueRegressor(model, data, q[k], v[k], a[k])[keep]
    return out.reshape(-1, out.shape[2])


def pseudo_inertia(params10: np.ndarray) -> np.ndarray:
    """4x4 pseudo-inertia [[Sigma, h], [h^T, m]], Sigma = tr(I)/2 I3 - I; positive semidefinite
    iff the body is physically realisable, positive definite iff by a non-degenerate body (Wensing,
    Kim, Slotine 2017)."""
    m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = params10
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    out = np.zeros((4, 4))
    out[:3, :3] = np.trace(inertia) / 2 * np.eye(3) - inertia
    out[:3, 3] = out[3, :3] = (hx, hy, hz)
    out[3, 3] = m
    return out


def physical_consistency(model: pin.Model, params: np.ndarray) -> dict[str, float]:
    """Smallest eigenvalue of each body's pseudo-inertia (> 0: physically consistent), by joint name."""
    p = np.asarray(params, float).reshape(model.njoints - 1, 10)
    return {model.names[j]: float(np.linalg.eigvalsh(pseudo_inertia(p[j - 1]))[0]) for j in range(1, model.njoints)}


def params_from_pseudo_inertia(J: np.ndarray) -> np.ndarray:
    """Inverse of `pseudo_inertia` (linear): [m, h, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] with I = tr(Sigma) I3 - Sigma."""
    sigma = J[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return np.array([J[3, 3], *J[:3, 3], inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2],
                     inertia[1, 2], inertia[2, 2]])


def is_physically_consistent(params10: np.ndarray, rtol: float = 1e-9) -> bool:
    """True iff the body's pseudo-inertia is positive semidefinite, which is necessary and sufficient
    for the 10 parameters to be those of some mass distribution (Wensing, Kim, Slotine 2017).
    Eigenvalues down to -rtol x the largest one are taken as rounding of a zero."""
    eig = np.linalg.eigvalsh(pseudo_inertia(np.asarray(params10, float)))
    return bool(eig[0] >= -rtol * max(abs(eig[-1]), np.finfo(float).tiny))
