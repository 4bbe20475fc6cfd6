"""The identification regressor restricted to the joints whose torque was recorded, and the
unconstrained (ordinary weighted least-squares) fit of its base parameters.

Per sample and recorded joint j:  tau_j = Y_j(q, v, a) pi + Fc_j tanh(v_j / eps) + Fv_j v_j + tau0_j
+ Ia_j a_j + K_j q_j, with pi the 10 inertial parameters of every body (inertial.py), Fc, Fv Coulomb and
viscous friction, tau0 a torque offset, Ia the rotor inertia reflected to the joint (armature) and K a
spring (with the offset: a counterbalance, constant plus linear in position). Asymmetric friction
splits a term by the sign of the speed: coulomb_asymmetric gives Fc+ max(tanh, 0) + Fc- min(tanh, 0)
(columns coulomb_pos, coulomb_neg), viscous_asymmetric Fv+ max(v, 0) + Fv- min(v, 0); with the
symmetric term they span one more column each.
Joints without recorded torque stay in the model (their bodies load the others) but give no rows.
Base parameters are chosen by robocal.estimation.identifiability.select_base_parameters on the weighted
regressor; the weights 1/sigma_j come from the residuals of the pass before (three passes); standard errors allow for
the filtered noise's correlation across samples (serial_correlation.py). See docs/dynamics_tiago.md.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.dynamics.inertial import parameter_names, torque_regressor
from robocal.errors import InputError
from robocal.estimation.identifiability import BaseSelection, covariance, select_base_parameters

EXTRA_TERMS = ("coulomb", "viscous", "offset", "armature")
#: every per-joint term a config may name (model.terms, model.candidate_terms); delay is not a column
#: (term_selection.py shifts the torque instead)
TERMS = EXTRA_TERMS + ("spring", "coulomb_asymmetric", "viscous_asymmetric")
#: the regressor columns of each term
COLUMNS = {"coulomb": ("coulomb",), "viscous": ("viscous",), "offset": ("offset",), "armature": ("armature",),
           "spring": ("spring",), "coulomb_asymmetric": ("coulomb_pos", "coulomb_neg"),
           "viscous_asymmetric": ("viscous_pos", "viscous_neg")}
#: an asymmetric term replaces its symmetric one
REPLACES = {"coulomb_asymmetric": "coulomb", "viscous_asymmetric": "viscous"}


def term_columns(terms, replace: bool = True) -> tuple[str, ...]:
    """The column kinds of a joint's terms, an asymmetric term standing in for its symmetric one (with
    replace False both are kept: the candidate search's regressor)."""
    if replace:
        terms = [t for t in terms if not any(REPLACES.get(o) == t for o in terms)]
    return tuple(c for t in terms for c in COLUMNS[t])


@dataclass
class Regressor:
    """X (T nr, n_inertial + n_extra) rows sample-major over the recorded joints; names of the
    columns; n_inertial: the first columns are the bodies' inertial parameters."""

    X: np.ndarray
    names: list[str]
    n_inertial: int
    recorded: list[int]

    def split(self, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return params[: self.n_inertial], params[self.n_inertial:]

    def samples(self, mask: np.ndarray) -> "Regressor":
        """The rows of the samples selected by a boolean mask over samples."""
        nr = len(self.recorded)
        X = self.X.reshape(-1, nr, self.X.shape[1])[mask].reshape(-1, self.X.shape[1])
        return Regressor(X, self.names, self.n_inertial, self.recorded)

    def columns(self, names: list[str]) -> "Regressor":
        """The inertial columns and the extra columns named (in that order)."""
        idx = [self.names.index(n) for n in names]
        X = np.concatenate([self.X[:, :self.n_inertial], self.X[:, idx]], axis=1)
        return Regressor(X, self.names[:self.n_inertial] + list(names), self.n_inertial, self.recorded)

    def transformed(self, function) -> "Regressor":
        """A regressor whose (T, nr, columns) array went through `function` along its sample axis."""
        nr = len(self.recorded)
        X = function(self.X.reshape(-1, nr, self.X.shape[1]))
        return Regressor(X.reshape(-1, self.X.shape[1]), self.names, self.n_inertial, self.recorded)


def build_regressor(model: pin.Model, q: np.ndarray, v: np.ndarray, a: np.ndarray, recorded: list[int],
                    terms=EXTRA_TERMS, coulomb_width: float | np.ndarray = 0.01, replace: bool = True) -> Regressor:
    """Regressor over the velocity indices `recorded` (model order); q (T, nq), v, a (T, nv).
    terms: names of TERMS for every recorded joint, or {velocity index: names} per joint; coulomb_width:
    tanh width (velocity units) per recorded joint, or one for all."""
    per_joint = terms if isinstance(terms, dict) else {j: tuple(terms) for j in recorded}
    for names in per_joint.values():
        for term in names:
            if term not in TERMS:
                raise InputError(f"unknown term '{term}'; known: {', '.join(TERMS)}", source="config",
                                 field="model.terms")
    T, nv = v.shape
    Y = torque_regressor(model, q, v, a, recorded).reshape(T, len(recorded), -1)
    nr = len(recorded)
    width = np.zeros(nv)
    width[recorded] = np.broadcast_to(np.asarray(coulomb_width, float), (nr,))
    if np.any(width[recorded] <= 0):
        raise InputError("the Coulomb tanh width must be > 0", source="config", field="model.coulomb_width")
    width[width == 0] = 1.0                  # joints without rows: any width, their column is unused
    cols = column_values(_joint_positions(model, q), v, a, width)
    kinds = [term_columns(per_joint.get(j, ()), replace) for j in recorded]
    extra = np.zeros((T, nr, sum(len(k) for k in kinds)))
    names, col = [], 0
    for k, (j, joint_kinds) in enumerate(zip(recorded, kinds)):
        for kind in joint_kinds:
            extra[:, k, col] = cols[kind][:, j]
            names.append(f"{_velocity_name(model, j)}.{kind}")
            col += 1
    X = np.concatenate([Y, extra], axis=2).reshape(T * nr, -1)
    return Regressor(X, parameter_names(model) + names, Y.shape[2], list(recorded))


def column_values(q: np.ndarray, v: np.ndarray, a: np.ndarray, width) -> dict[str, np.ndarray]:
    """Every extra column kind's values from joint positions, velocities, accelerations (arrays of one shape)
    and the Coulomb tanh width (broadcast against them)."""
    smooth_sign = np.tanh(v / width)
    return {"coulomb": smooth_sign, "viscous": v, "offset": np.ones_like(v), "armature": a, "spring": q,
            "coulomb_pos": np.maximum(smooth_sign, 0.0), "coulomb_neg": np.minimum(smooth_sign, 0.0),
            "viscous_pos": np.maximum(v, 0.0), "viscous_neg": np.minimum(v, 0.0)}


def _joint_positions(model: pin.Model, q: np.ndarray) -> np.ndarray:
    """(T, nv): each one-axis joint's position at its velocity index (the spring's column)."""
    out = np.zeros((len(q), model.nv))
    for j in range(1, model.njoints):
        joint = model.joints[j]
        if joint.nq == 1 and joint.nv == 1:
            out[:, joint.idx_v] = q[:, joint.idx_q]
    return out


def _velocity_name(model: pin.Model, idx_v: int) -> str:
    for j in range(1, model.njoints):
        if model.joints[j].idx_v <= idx_v < model.joints[j].idx_v + model.joints[j].nv:
            return model.names[j]
    raise InputError(f"no joint has velocity index {idx_v}", field="joints")


@dataclass
class BaseFit:
    """Unconstrained fit. selection: the base-parameter choice; values: base parameters; std: their
    standard errors, allowing for the filtered noise's correlation across samples (inflation, the
    variance factor of serial_correlation.py); std_independent: the textbook standard errors, which
    assume independent rows; sigma (nr,) per-joint residual RMS of the weighted pass before the final one,
    the weights of the final fit (torque units; beta minimises that weighted objective);
    condition: condition number of the column-scaled weighted base regressor; dof: rows - parameters."""

    selection: BaseSelection
    values: np.ndarray
    std: np.ndarray
    sigma: np.ndarray
    condition: float
    dof: int
    std_independent: np.ndarray | None = None
    inflation: float = 1.0

    @property
    def names(self) -> list[str]:
        return [self.selection.names[i] for i in self.selection.independent]

    def predict(self, reg: Regressor) -> np.ndarray:
        """Torques (T, nr) of the recorded joints on another regressor of the same model."""
        return (reg.X[:, self.selection.independent] @ self.values).reshape(-1, len(reg.recorded))


def row_weights(sigma: np.ndarray, n_samples: int) -> np.ndarray:
    return np.tile(1.0 / np.asarray(sigma, float), n_samples)


def fit_base(reg: Regressor, tau: np.ndarray, rtol: float = 1e-6, inflation: float = 1.0) -> BaseFit:
    """Weighted least squares of tau (T, nr) on the base columns of `reg`. inflation: the factor by
    which correlation across samples inflates the variances (serial_correlation.py)."""
    tau = np.asarray(tau, float)
    nr = len(reg.recorded)
    if tau.shape[1] != nr or tau.size != reg.X.shape[0]:
        raise InputError(f"torques must be (T, {nr}) matching the regressor", field="effort")
    y = tau.reshape(-1)
    sigma = np.ones(nr)
    # weights from the residuals of the pass before: unweighted, weighted once, then the final fit; the
    # returned sigma is the one the final fit weighed by, so beta minimises exactly that objective
    for final in (False, False, True):
        w = row_weights(sigma, len(tau))
        sel = select_base_parameters(reg.X * w[:, None], reg.names, rtol)
        Xb = reg.X[:, sel.independent] * w[:, None]
        beta, *_ = np.linalg.lstsq(Xb, y * w, rcond=None)
        resid = (y - reg.X[:, sel.independent] @ beta).reshape(-1, nr)
        if not final:
            sigma = np.maximum(np.sqrt(np.mean(resid**2, axis=0)), 1e-12 * max(1.0, np.abs(y).max()))
    dof = max(len(y) - sel.rank, 1)
    s2 = float(np.sum((resid.reshape(-1) * w) ** 2) / dof)
    std_independent = np.sqrt(np.diag(covariance(Xb, s2)))
    return BaseFit(sel, beta, std_independent * np.sqrt(inflation), sigma, float(sel.condition), dof,
                   std_independent, float(inflation))
