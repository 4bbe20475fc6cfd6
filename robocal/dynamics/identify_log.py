"""Dynamic identification of a joint log: filter, fit (unconstrained and physically consistent), validate on
a held-out window, and estimate the external force in free motion.

`identify_log(model, log, recorded, tau, options)` returns an `IdentifyResult`. Models compared side by
side: 'cad' (the URDF's inertias, no friction), 'ols' (base parameters by weighted least squares),
'consistent' (every body realisable, the CAD values as a prior; consistent_fit.py). The command
`robocal identify` (robocal.workflows.identify) reads the config and the log and writes the result.
See docs/dynamics_tiago.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
from scipy.stats import chi2

from robocal.dynamics.consistent_fit import ConsistentFit, fit_consistent
from robocal.dynamics.constraint_cost import ConstraintCost, constraint_costs
from robocal.dynamics.external_force import ExternalForceEstimator
from robocal.dynamics.filtering import ProcessedLog, SignalOptions, parallel_filter, process_log
from robocal.dynamics.identification import base_values_of
from robocal.dynamics.inertial import is_physically_consistent, parameter_vector, pseudo_inertia, with_parameters
from robocal.dynamics.log_loading import JointLog
from robocal.dynamics.prior_weight import DEFAULT_GRID, PriorWeightChoice, holdout_choice, within_noise_choice
from robocal.dynamics.reduced_model import model_columns, velocity_index
from robocal.dynamics.regression import EXTRA_TERMS, BaseFit, Regressor, build_regressor, fit_base
from robocal.dynamics.serial_correlation import filtered_noise_inflation
from robocal.dynamics.wrench import WrenchMapper
from robocal.errors import InputError

MODELS = ("cad", "ols", "consistent")


@dataclass(kw_only=True)
class IdentifyOptions:
    """How to identify: the signal processing, the training and validation windows (s, log time), the
    extra model terms and the prior rule (docs/dynamics_tiago.md); source names them in error messages."""

    signal: SignalOptions = field(default_factory=SignalOptions)
    train: tuple[float, float]
    validate: tuple[float, float]
    min_motion: float = 0.01
    terms: tuple[str, ...] = EXTRA_TERMS
    coulomb_width: float = 0.05
    prior_rule: str = "within_noise"
    prior_grid: tuple[float, ...] = DEFAULT_GRID
    prior_split: float = 0.75
    wrench_frame: str | None = None
    source: str = "identification"


@dataclass
class IdentifyResult:
    """config: the options (a workflow passes its whole config, which extends them); model: the reduced CAD model; recorded: recorded joint names (model order);
    processed: the filtered log (full rate); train, check: masks over its decimated samples
    (processed.decimated(processed.t)); ols, consistent,
    prior: the fits; consistency: {body: (smallest pseudo-inertia eigenvalue, realisable)} of the
    consistent model; validation: {model: {'rmse': [...], 'percent_of_range': [...],
    'rmse_against_logged': [...]}} on the validation window (against the filtered torque, and against the
    logged torque itself); training_rms: {model: [...]}; torque_range: per joint on the validation
    window; within_noise: comparison of the consistent and unconstrained fits; wrench_rms:
    {model: [fx, fy, fz] N}; curves: validation time, measured and predicted torques for plots."""

    config: IdentifyOptions
    model: pin.Model
    recorded: list[str]
    processed: ProcessedLog
    train: np.ndarray
    check: np.ndarray
    ols: BaseFit
    consistent: ConsistentFit
    prior: PriorWeightChoice
    consistency: dict
    validation: dict
    training_rms: dict
    torque_range: list
    within_noise: dict
    wrench_rms: dict
    curves: dict = field(repr=False, default_factory=dict)
    constraint_costs: list[ConstraintCost] = field(default_factory=list)
    regressors: dict[str, Regressor] = field(repr=False, default_factory=dict)

    def consistent_model(self) -> pin.Model:
        """The reduced model carrying the consistent inertial parameters and rotor inertias."""
        out = with_parameters(self.model, self.consistent.inertial)
        names = self.consistent_extra_names()
        for value, name in zip(self.consistent.extra, names):
            joint, term = name.rsplit(".", 1)
            if term == "armature":
                out.armature[velocity_index(out, joint)] = value
        return out

    def consistent_extra_names(self) -> list[str]:
        """Names of the extra terms (friction, offsets, rotor inertias), in `consistent.extra` order."""
        return self.ols.selection.names[10 * (self.model.njoints - 1):]


def identify_log(model: pin.Model, log: JointLog, recorded: list[str], tau: np.ndarray,
                 options: IdentifyOptions) -> IdentifyResult:
    """Identify `model`'s inertial and friction parameters from a joint log (see the module docstring).

    log: positions and velocities of `log.joints` (SI); recorded: the joints whose torque was logged, in
    model order; tau: (T, len(recorded)) their torques (N m, or N for prismatic joints)."""
    cfg = options
    rec_idx = [velocity_index(model, j) for j in recorded]
    proc = process_log(log.t, model_columns(model, log.joints, log.q), model_columns(model, log.joints, log.v),
                       tau, cfg.signal, spectrum_window=cfg.train)
    width = cfg.coulomb_width * np.sqrt(np.mean(proc.v[_in(proc.t, cfg.train)][:, rec_idx] ** 2, axis=0))
    # parallel filtering: regressor at the full rate, same low-pass as the torques, then decimation
    reg_all = build_regressor(model, proc.q, proc.v, proc.a, rec_idx, cfg.terms, width).transformed(
        lambda X: parallel_filter(proc, X))
    t_dec = proc.decimated(proc.t)
    tau_dec = proc.decimated(proc.effort)
    # the zero-phase filter spreads each sample over a few cut-off periods: training samples that close to
    # the validation window would carry its data into the fit, so they are left out
    guard = cfg.signal.edge_periods / proc.cutoff_hz
    train = _in(t_dec, cfg.train) & ~_in(t_dec, (cfg.validate[0] - guard, cfg.validate[1] + guard))
    check = _in(t_dec, cfg.validate)
    proc.choices.append(f"training samples within {guard:.3g} s ({cfg.signal.edge_periods:g} cut-off periods) of "
                        f"the validation window left out of the fit: the zero-phase filter would carry its data "
                        f"into them")
    if train.sum() < 10 or check.sum() < 10:
        raise InputError(f"after filtering, {train.sum()} training and {check.sum()} validation samples remain; "
                         "widen the windows", source=cfg.source, field="windows")

    def regressor(mask) -> Regressor:
        return reg_all.samples(mask)

    reg_train, reg_check = regressor(train), regressor(check)
    tau_train, tau_check = tau_dec[train], tau_dec[check]
    inflation = filtered_noise_inflation(proc.cutoff_hz, proc.fs_raw, cfg.signal.order, proc.decimation)
    ols = fit_base(reg_train, tau_train, inflation=inflation)
    if ols.selection.rank == 0:
        raise InputError("the training window identifies no parameter", source=log.files["position"],
                         field="windows.train")
    cad = parameter_vector(model)
    rss_ols, noise_unit = _noise_scale(reg_train, tau_train, ols)
    if cfg.prior_rule == "holdout":
        prior = _holdout_choice(cfg, reg_all, t_dec, tau_dec, train, guard, ols.sigma, cad)
    else:
        prior = within_noise_choice(reg_train, tau_train, ols.sigma, cad, cfg.prior_grid, rss_ols, noise_unit,
                                    float(chi2.ppf(0.95, ols.selection.rank)))
    consistent = fit_consistent(reg_train, tau_train, ols.sigma, cad, prior.chosen)
    predict = {"cad": lambda reg: (reg.X[:, :reg.n_inertial] @ cad).reshape(-1, len(rec_idx)),
               "ols": ols.predict, "consistent": consistent.predict}
    t_range = (tau_check.max(axis=0) - tau_check.min(axis=0)).tolist()
    # the logged torque itself at the same times (linear interpolation, no filter): a target that does not
    # depend on robocal's cut-off, for comparing with other tools
    logged = np.column_stack([np.interp(t_dec[check], log.t, tau[:, k]) for k in range(len(rec_idx))])
    validation, training_rms = {}, {}
    curves = {"t": t_dec[check], "measured": tau_check, "logged": logged}
    for name, f in predict.items():
        pred = f(reg_check)
        rmse = np.sqrt(np.mean((pred - tau_check) ** 2, axis=0))
        validation[name] = {"rmse": rmse.tolist(), "percent_of_range": (100 * rmse / np.array(t_range)).tolist(),
                            "rmse_against_logged": np.sqrt(np.mean((pred - logged) ** 2, axis=0)).tolist()}
        training_rms[name] = np.sqrt(np.mean((f(reg_train) - tau_train) ** 2, axis=0)).tolist()
        curves[name] = pred
    bodies = {model.names[j]: p for j, p in zip(range(1, model.njoints), consistent.inertial.reshape(-1, 10))}
    consistency = {b: (float(np.linalg.eigvalsh(pseudo_inertia(p))[0]), is_physically_consistent(p))
                   for b, p in bodies.items()}
    beta_c = base_values_of(ols.selection, consistent.params)
    within = _within_noise(reg_train, tau_train, ols, consistent, beta_c, rss_ols, noise_unit)
    costs = constraint_costs(reg_train, tau_train, ols.sigma, cad, consistent,
                             [model.names[j] for j in range(1, model.njoints)], noise_unit)
    wrench = _wrench_rms(cfg, model, proc.decimated(proc.q)[check], rec_idx, {k: curves[k] for k in MODELS},
                         tau_check)
    return IdentifyResult(options, model, recorded, proc, train, check, ols, consistent, prior, consistency, validation,
                          training_rms, t_range, within, wrench, curves, costs,
                          {"train": reg_train, "check": reg_check})


def _holdout_choice(cfg: IdentifyOptions, reg_all, t_dec, tau_dec, train, guard, sigma, cad) -> PriorWeightChoice:
    """prior_weight.holdout_choice on the training window: its first prior_split fitted, the rest scored,
    the filter's reach left out between them (the part that scores a weight is not seen by its fit)."""
    n_fit = int(round(cfg.prior_split * train.sum()))
    idx = np.flatnonzero(train)
    first, second = np.zeros_like(train), np.zeros_like(train)
    first[idx[:n_fit]], second[idx[n_fit:]] = True, True
    first &= t_dec < t_dec[idx[min(n_fit, len(idx) - 1)]] - guard
    if first.sum() < 10 or second.sum() < 3:
        raise InputError(f"choosing the prior weight leaves {first.sum()} samples to fit and {second.sum()} to score "
                         f"(model.prior_split {cfg.prior_split:g}, {guard:.3g} s between them); widen the training "
                         "window", source=cfg.source, field="windows.train")
    prior = holdout_choice(reg_all.samples(first), tau_dec[first], reg_all.samples(second), tau_dec[second],
                           sigma, cad, cfg.prior_grid, cfg.prior_split)
    prior.gap_s = float(t_dec[second].min() - t_dec[first].max())
    return prior

def _noise_scale(reg: Regressor, tau: np.ndarray, ols: BaseFit) -> tuple[float, float]:
    """(the unconstrained fit's weighted residual sum of squares, the weighted cost of one noise unit: its
    residual variance times the filtered noise's inflation)."""
    w = np.tile(1.0 / ols.sigma, len(tau))
    rss_ols = float(np.sum(((ols.predict(reg).reshape(-1) - tau.reshape(-1)) * w) ** 2))
    return rss_ols, rss_ols / ols.dof * ols.inflation

def _within_noise(reg: Regressor, tau: np.ndarray, ols: BaseFit, fit: ConsistentFit, beta_c: np.ndarray,
                  rss_ols: float, noise_unit: float) -> dict:
    """How far the consistent fit lies from the unconstrained one, in the unconstrained fit's noise:
    the weighted residual increase (= squared Mahalanobis distance of its base parameters from the
    OLS estimate, the model being linear in them) divided by the filtered noise's variance inflation
    (serial_correlation.py), against the chi-square 95 % quantile. rss_ols, noise_unit: `_noise_scale`;
    fit.data_cost is the fit's weighted residual on the same rows with the same weights."""
    pred_ols, pred_fit = ols.predict(reg), fit.predict(reg)
    increase = (fit.data_cost - rss_ols) / (rss_ols / ols.dof)
    p = ols.selection.rank
    return {"distance_in_noise_units": increase / ols.inflation, "noise_inflation": ols.inflation,
            "noise_unit": noise_unit,
            "residual_increase_independent_rows": increase, "chi2_95": float(chi2.ppf(0.95, p)),
            "base_parameters": p,
            "rms_ratio": (np.sqrt(np.mean((pred_fit - tau) ** 2, axis=0))
                          / np.sqrt(np.mean((pred_ols - tau) ** 2, axis=0))).tolist(),
            "max_base_deviation_in_std": float(np.max(np.abs(beta_c - ols.values) / ols.std))}

def _in(t: np.ndarray, window: tuple[float, float]) -> np.ndarray:
    return (t >= window[0]) & (t < window[1])

def _wrench_rms(cfg: IdentifyOptions, model, q, rec_idx, predictions, measured) -> dict:
    """RMS (N) per world axis of the force at the wrench frame that explains the torque the model
    misses (measured - predicted, recorded joints only; force only: the recorded joints are too few
    to resolve a moment as well)."""
    name = cfg.wrench_frame or model.frames[-1].name
    if not model.existFrame(name):
        raise InputError(f"frame '{name}' is not in the model", source=cfg.source, field="wrench.frame")
    est = ExternalForceEstimator(model, model.getFrameId(name))
    J = est.jacobians(q)[:, :, rec_idx]
    mapper = WrenchMapper(force_only=True)
    return {k: np.sqrt(np.mean(mapper.map(J, measured - pred).force ** 2, axis=0)).tolist()
            for k, pred in predictions.items()} | {"frame": name}
