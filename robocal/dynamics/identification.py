"""Dynamic identification from free-motion logs (spec §12): inertial base parameters, friction, and
the torque-constant scale when a known reference fixes it.

Model, per sample: alpha * tau_meas = Y(q, v, a) pi + Phi(v) phi + Y_p pi_p
  tau_meas = actuator.torque(I) with the nominal torque constants; alpha (global or per joint) the
  unknown scale of the torque constants; pi the inertial parameters (only base combinations are
  identifiable: `robocal.estimation.identifiability.select_base_parameters` picks them deterministically);
  phi friction per joint; pi_p a known payload (segments recorded with it; zero otherwise).
Without a segment carrying a known payload the equations are homogeneous in (alpha, pi, phi): the
scale is unobservable, the result says so and keeps alpha = 1 (the nominal torque constants).
Rows are weighted by the torque noise per joint (given, or estimated from the residuals), and
standard errors come from the weighted least-squares covariance.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.estimation.identifiability import BaseSelection, covariance, select_base_parameters
from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.friction import FRICTION_TERMS, FrictionModel
from robocal.dynamics.inertial import parameter_names, parameter_vector, physical_consistency, torque_regressor, with_parameters

log = logging.getLogger(__name__)

SCALES = ("fixed", "global", "per_joint")


@dataclass
class Segment:
    """One log: q (T, nq), v, a (T, nv) (from a documented differentiation scheme or analytic),
    current (T, nv) A; payload: known pin.Inertia attached at frame `payload_frame` (or None)."""

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    current: np.ndarray
    payload: pin.Inertia | None = None
    payload_frame: int | None = None


@dataclass
class DynamicIdentificationResult:
    """Identified quantities with standard errors (same units as the parameters).

    base_names / base_values / base_std: inertial+friction base parameters (regrouped combinations
    named after their kept column); friction: FrictionModel (dropped friction terms at 0);
    scale / scale_std: torque-constant scale per joint (true K_t = scale * nominal);
    scale_observable: False when no reference fixes it (then scale = 1, std = nan);
    selection: the BaseSelection; residual_rms (nv,) N m; sigma_torque (nv,) N m used as weights;
    covariance of all estimated unknowns (base parameters then scale); message: plain summary.
    """

    base_names: list[str]
    base_values: np.ndarray
    base_std: np.ndarray
    friction: FrictionModel
    scale: np.ndarray
    scale_std: np.ndarray
    scale_observable: bool
    selection: BaseSelection
    residual_rms: np.ndarray
    sigma_torque: np.ndarray
    covariance: np.ndarray
    message: str
    n_inertial: int = field(repr=False, default=0)

    def full_parameters(self, reference: np.ndarray) -> np.ndarray:
        """One full vector (inertial + friction columns) reproducing the base values: dropped
        columns keep their `reference` values, kept ones absorb the regrouping."""
        ref = np.asarray(reference, float).copy()
        sel = self.selection
        ref[sel.independent] = self.base_values - sel.regrouping @ ref[sel.dependent]
        return ref

    def model(self, nominal: pin.Model) -> pin.Model:
        """A model whose rnea reproduces the identified torques (dropped parameters at nominal).
        Check `physical_consistency` on it before trusting it for simulation."""
        ref = np.r_[parameter_vector(nominal), np.zeros(len(self.selection.names) - self.n_inertial)]
        return with_parameters(nominal, self.full_parameters(ref)[: self.n_inertial])

    def consistency(self, nominal: pin.Model) -> dict[str, float]:
        """Smallest pseudo-inertia eigenvalue per body of `model(nominal)`; all > 0 means that
        realisation is physically consistent (a sufficient test: another realisation may be)."""
        return physical_consistency(nominal, parameter_vector(self.model(nominal)))


def friction_columns(friction: FrictionModel, v: np.ndarray, terms: tuple[str, ...]) -> tuple[np.ndarray, list[str]]:
    """(T nv, nv len(terms)) block regressor and names 'joint<j>.<term>'."""
    idx = [FRICTION_TERMS.index(t) for t in terms]
    basis = friction.regressor(v)[..., idx]                 # (T, nv, k)
    T, n, k = basis.shape
    cols = np.zeros((T, n, n, k))
    cols[:, np.arange(n), np.arange(n), :] = basis
    return cols.reshape(T * n, n * k), [f"joint{j}.{t}" for j in range(n) for t in terms]


def _payload_torque(model: pin.Model, seg: Segment) -> np.ndarray:
    """Joint torques (T nv,) that the known payload alone requires."""
    if seg.payload is None:
        return np.zeros(len(seg.q) * model.nv)
    frame = model.frames[seg.payload_frame]
    j = frame.parentJoint
    pi_p = frame.placement.act(seg.payload).toDynamicParameters()
    Y = torque_regressor(model, seg.q, seg.v, seg.a)
    return Y[:, 10 * (j - 1): 10 * j] @ pi_p


def identify_dynamics(model: pin.Model, segments: list[Segment], actuator: ActuatorModel,
                      friction: FrictionModel, terms: tuple[str, ...] = ("coulomb", "viscous", "offset"),
                      scale: str = "fixed", current_noise: np.ndarray | float | None = None,
                      rtol: float = 1e-8) -> DynamicIdentificationResult:
    """Fit base inertial parameters, friction (`terms`) and optionally the torque-constant scale.

    friction gives the fixed shape constants (tanh width, Stribeck velocity); its values are ignored.
    scale: 'fixed' (nominal K_t), 'global' (one factor) or 'per_joint'. current_noise A per joint
    (std of the current readings) sets the weights; when None it is estimated from the residuals.
    """
    if scale not in SCALES:
        raise InputError(f"scale must be one of {SCALES}, got '{scale}'", field="scale")
    if not segments:
        raise InputError("no data segments given", field="segments")
    for t in terms:
        if t not in FRICTION_TERMS:
            raise InputError(f"unknown friction term '{t}'; known: {FRICTION_TERMS}", field="terms")
    nv = model.nv
    Y, F, tau, ref = [], [], [], []
    for i, seg in enumerate(segments):
        if seg.current.shape != seg.v.shape or seg.q.shape[0] != seg.v.shape[0]:
            raise InputError(f"segment {i}: q, v, a and current must have matching (T, n) shapes",
                             field="current", row=i)
        Y.append(torque_regressor(model, seg.q, seg.v, seg.a))
        F.append(friction_columns(friction, seg.v, terms)[0])
        tau.append(actuator.torque(seg.current).reshape(-1))
        ref.append(_payload_torque(model, seg))
    Y, F, tau, ref = (np.concatenate(x) for x in (Y, F, tau, ref))
    names = parameter_names(model) + friction_columns(friction, np.zeros((1, nv)), terms)[1]
    X = np.hstack([Y, F])
    joint_of_row = np.tile(np.arange(nv), len(tau) // nv)
    if current_noise is not None:
        sig_i = np.broadcast_to(np.asarray(current_noise, float), (nv,))
        sigma = np.sqrt(np.diag(actuator.gain @ np.diag(sig_i**2) @ actuator.gain.T))
        estimated = False
    else:
        sigma = np.ones(nv)
        estimated = True
    for _ in range(2 if estimated else 1):
        w = 1.0 / sigma[joint_of_row]
        selection = select_base_parameters(X * w[:, None], names, rtol)
        Xb = X[:, selection.independent]
        sol, A, resid, observable = _fit(Xb, tau, ref, w, joint_of_row, nv, scale, selection.rank, rtol)
        rms = np.sqrt(np.bincount(joint_of_row, resid**2, nv) / (len(tau) // nv))
        if estimated:
            sigma = np.maximum(rms, 1e-12 * max(1.0, np.abs(tau).max()))
    dof = max(len(tau) - A.shape[1], 1)
    s2 = float(np.sum((resid * w)**2) / dof) if estimated else 1.0     # with the weights used
    cov = covariance(A, s2)
    std = np.sqrt(np.diag(cov))
    p = selection.rank
    beta, beta_std = sol[:p], std[:p]
    if scale != "fixed" and observable:
        gamma, gamma_std = sol[p:], std[p:]                  # gamma = 1/alpha
        alpha, alpha_std = 1.0 / gamma, gamma_std / gamma**2
        if scale == "global":
            alpha, alpha_std = np.full(nv, alpha[0]), np.full(nv, alpha_std[0])
    else:
        alpha, alpha_std = np.ones(nv), np.full(nv, np.nan)
    if scale != "fixed" and not observable:
        message = ("the torque-constant scale is not observable from these data (no known reference "
                   "such as a payload): it is fixed at the nominal torque constants")
        log.info(message)
    else:
        message = f"{p} base parameters identified (condition {selection.condition:.3g})"
    fric = _friction_from(beta, selection, names, friction, terms, Y.shape[1])
    return DynamicIdentificationResult([names[i] for i in selection.independent], beta, beta_std, fric, alpha,
                                       alpha_std, observable, selection, rms, sigma, cov, message,
                                       n_inertial=Y.shape[1])


def _fit(Xb, tau, ref, w, joint_of_row, nv, scale, rank, rtol, iterations=20):
    """Weighted fit of tau = gamma_row (Xb beta + ref), gamma = 1/alpha (1 when fixed or unobservable).

    The noise stays on the left (in tau), so the estimate has no errors-in-variables bias.
    Returns (solution [beta, gamma], weighted Jacobian, residual, scale observable)."""
    beta, *_ = np.linalg.lstsq(Xb * w[:, None], (tau - ref) * w, rcond=None)
    if scale == "fixed":
        return beta, Xb * w[:, None], tau - ref - Xb @ beta, True
    # structural test on the model-predicted torques (noise would hide a rank drop): the scale is
    # observable iff its columns leave the span of the regressor, which needs a known reference
    predicted = _scale_columns(Xb @ beta + ref, joint_of_row, nv, scale)
    observable = select_base_parameters(np.hstack([Xb, predicted]) * w[:, None], None, rtol).rank \
        == rank + predicted.shape[1]
    if not observable:
        return beta, Xb * w[:, None], tau - ref - Xb @ beta, False
    gamma = np.ones(predicted.shape[1])

    def linearise(beta, gamma):
        g_row = np.full(len(tau), gamma[0]) if scale == "global" else gamma[joint_of_row]
        model = Xb @ beta + ref
        jac = np.hstack([Xb * g_row[:, None], _scale_columns(model, joint_of_row, nv, scale)]) * w[:, None]
        return jac, tau - g_row * model

    for _ in range(iterations):                               # Gauss-Newton on the bilinear model
        A, resid = linearise(beta, gamma)
        step, *_ = np.linalg.lstsq(A, resid * w, rcond=None)
        beta, gamma = beta + step[:rank], gamma + step[rank:]
        if np.max(np.abs(step[rank:])) < 1e-13 and np.linalg.norm(step[:rank]) <= 1e-12 * np.linalg.norm(beta):
            break
    A, resid = linearise(beta, gamma)
    return np.r_[beta, gamma], A, resid, True


def _scale_columns(tau: np.ndarray, joint_of_row: np.ndarray, nv: int, scale: str) -> np.ndarray:
    if scale == "fixed":
        return np.zeros((len(tau), 0))
    if scale == "global":
        return tau[:, None]
    S = np.zeros((len(tau), nv))
    S[np.arange(len(tau)), joint_of_row] = tau
    return S


def _friction_from(beta, selection, names, template, terms, n_inertial) -> FrictionModel:
    params = np.zeros((template.n, 4))
    for value, col in zip(beta, selection.independent):
        if col >= n_inertial:
            joint, term = names[col].split(".")
            params[int(joint[5:]), FRICTION_TERMS.index(term)] = value
    return template.with_parameters(params)


def base_values_of(selection: BaseSelection, full: np.ndarray) -> np.ndarray:
    """Base parameters of a full parameter vector: kept + regrouping @ dropped."""
    full = np.asarray(full, float)
    return full[selection.independent] + selection.regrouping @ full[selection.dependent]


@dataclass
class PayloadResult:
    """Payload at a frame: params (10,) in the frame [m, m c, I about the frame origin], std (10,),
    identifiable: names of the payload parameters the data determine (others are left at 0)."""

    params: np.ndarray
    std: np.ndarray
    identifiable: list[str]

    @property
    def mass(self) -> float:
        return float(self.params[0])

    @property
    def com(self) -> np.ndarray:
        return self.params[1:4] / self.params[0]


def identify_payload(model: pin.Model, frame_id: int, segment: Segment, actuator: ActuatorModel,
                     friction: FrictionModel, current_noise: np.ndarray | float, rtol: float = 1e-8) -> PayloadResult:
    """Identify an unknown payload at `frame_id` from a log taken while carrying it, with the robot's
    own model (`model`, `friction`, `actuator`) already identified: the torque the model does not
    explain is Y_body(q, v, a) T pi_payload, T moving frame parameters to the joint frame."""
    seg = segment
    nv = model.nv
    frame = model.frames[frame_id]
    j = frame.parentJoint
    data = model.createData()
    rest = actuator.torque(seg.current) - friction.torque(seg.v)
    for k in range(len(seg.q)):
        rest[k] -= pin.rnea(model, data, seg.q[k], seg.v[k], seg.a[k])
    Yb = torque_regressor(model, seg.q, seg.v, seg.a)[:, 10 * (j - 1): 10 * j]
    # frame -> joint parameters is linear: take differences about a valid inertia
    base = pin.Inertia(1.0, np.zeros(3), np.eye(3))
    b0 = frame.placement.act(base).toDynamicParameters()
    T = np.column_stack([frame.placement.act(pin.Inertia.FromDynamicParameters(base.toDynamicParameters() + e))
                         .toDynamicParameters() - b0 for e in np.eye(10)])
    X = Yb @ T
    sig_i = np.broadcast_to(np.asarray(current_noise, float), (nv,))
    sigma = np.sqrt(np.diag(actuator.gain @ np.diag(sig_i**2) @ actuator.gain.T))
    w = np.tile(1.0 / sigma, len(seg.q))
    names = [f"payload.{t}" for t in ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")]
    sel = select_base_parameters(X * w[:, None], names, rtol)
    Xi = X[:, sel.independent] * w[:, None]
    sol, *_ = np.linalg.lstsq(Xi, rest.reshape(-1) * w, rcond=None)
    params, std = np.zeros(10), np.full(10, np.nan)
    params[sel.independent] = sol
    std[sel.independent] = np.sqrt(np.diag(covariance(Xi)))
    if sel.dependent:
        log.warning("payload parameters not identifiable from this motion: %s",
                    ", ".join(names[i] for i in sel.dependent))
    return PayloadResult(params, std, [names[i] for i in sel.independent])
