"""Dynamic identification of one or more joint logs: filter, choose the optional terms, fit (unconstrained,
and physically consistent and plausible), validate on held-out windows, estimate the free-motion force.

`identify_log(model, parts, recorded, options, bounds, channels=...)` returns an `IdentifyResult`; its rows are
the recorded joints' torques, or with a transmission the logged motors' (channels.py). Models compared side
by side: 'cad' (the URDF's inertias, no friction), 'ols' (base parameters by weighted least squares),
'consistent' (every body realisable and inside its plausibility bounds, the CAD values as a prior;
consistent_fit.py, plausible_bounds.py). The optional terms (spring, asymmetric friction, delay) are kept
or not by term_selection.py's rule on the training rows only. The command `robocal identify`
(robocal.workflows.identify) reads the config and the logs and writes the result. See docs/dynamics_tiago.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robocal.dynamics.channels import Channels
from robocal.dynamics.consistent_fit import ConsistentFit, fit_consistent
from robocal.dynamics.constraint_cost import ConstraintCost, constraint_costs
from robocal.dynamics.filtering import SignalOptions
from robocal.dynamics.identification import base_values_of
from robocal.dynamics.inertial import is_physically_consistent, parameter_vector, pseudo_inertia, with_parameters
from robocal.dynamics.log_parts import LogPart, PreparedPart, prepare_parts, stack
from robocal.dynamics.plausible_bounds import MARGIN_M, MASS_RATIO, BodyBound, LinearBounds, linear_bounds
from robocal.dynamics.prior_weight import DEFAULT_GRID, PriorWeightChoice, holdout_choice, within_noise_choice
from robocal.dynamics.reduced_model import velocity_index
from robocal.dynamics.regression import EXTRA_TERMS, BaseFit, Regressor, fit_base, row_weights, term_columns
from robocal.dynamics.serial_correlation import filtered_noise_inflation
from robocal.dynamics.term_selection import (ADDED_COLUMN, Projector, TermTest, added_column_tests, choose_delays,
                                             delay_grid)
from robocal.dynamics.validation import validate, wrench_rms
from robocal.errors import InputError
from robocal.dynamics.chi_square import chi2_quantile

MODELS = ("cad", "ols", "consistent")


@dataclass(kw_only=True)
class IdentifyOptions:
    """How to identify: the signal processing, the model terms (always in: terms; tried: candidate_terms,
    term_selection.py), the prior rule (prior_weight.py), the plausibility bounds (plausible: on or off;
    mass_ratio, margin_m, ellipsoids: plausible_bounds.py) and where the free-motion force is estimated;
    source names them in error messages. The logs and their windows are LogParts."""

    signal: SignalOptions = field(default_factory=SignalOptions)
    min_motion: float = 0.01
    terms: tuple[str, ...] = EXTRA_TERMS
    motor_terms: tuple[str, ...] = ()
    candidate_terms: tuple[str, ...] = ()
    delay_max_s: float = 0.2
    coulomb_width: float = 0.05
    prior_rule: str = "within_bounds_noise"
    prior_grid: tuple[float, ...] = DEFAULT_GRID
    prior_split: float = 0.75
    plausible: bool = True
    mass_ratio: tuple[float, float] = MASS_RATIO
    margin_m: float = MARGIN_M
    ellipsoids: dict = field(default_factory=dict)
    wrench_frame: str | None = None
    source: str = "identification"


@dataclass
class IdentifyResult:
    """config: the options (a workflow passes its whole config); model: the reduced CAD model; recorded:
    the channels' names (recorded joints in model order, or logged motors; channels.py); parts: the prepared
    logs (log_parts.py; parts[0].processed is `processed`); joint_terms: {joint: terms in the model}, per
    joint whose equation reaches a row; delays (nr,) s, per channel; term_tests: every candidate's
    test; ols, consistent, prior: the fits; consistent_std: standard errors of [inertial, extra];
    bounds: the plausibility bounds (empty when off); consistency: {body: (smallest pseudo-inertia
    eigenvalue, realisable)}; validation: {model: {'rmse', 'percent_of_range', 'rmse_against_logged'}} on
    the validation windows (empty without one); training_rms; torque_range; within_noise;
    wrench_rms; curves: validation times, measured and predicted torques; constraint_costs; notes: input
    notes said before any figure; coulomb_width: the tanh widths used per joint of joint_terms, motor_width
    per motor channel; channels: what the rows are."""

    config: IdentifyOptions
    model: pin.Model
    recorded: list[str]
    parts: list[PreparedPart]
    joint_terms: dict[str, tuple[str, ...]]
    delays: np.ndarray
    term_tests: list[TermTest]
    ols: BaseFit
    consistent: ConsistentFit
    consistent_std: np.ndarray
    prior: PriorWeightChoice
    bounds: list[BodyBound]
    consistency: dict
    validation: dict
    training_rms: dict
    torque_range: list
    within_noise: dict
    wrench_rms: dict
    curves: dict = field(repr=False, default_factory=dict)
    constraint_costs: list[ConstraintCost] = field(default_factory=list)
    regressors: dict[str, Regressor] = field(repr=False, default_factory=dict)
    notes: list[str] = field(default_factory=list)
    coulomb_width: np.ndarray = field(default_factory=lambda: np.zeros(0))
    channels: Channels | None = None
    motor_width: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def processed(self):
        return self.parts[0].processed

    @property
    def n_train(self) -> int:
        return int(sum(p.train.sum() for p in self.parts))

    @property
    def n_check(self) -> int:
        return int(sum(p.check.sum() for p in self.parts))

    def consistent_model(self) -> pin.Model:
        """The reduced model carrying the consistent inertial parameters and rotor inertias."""
        out = with_parameters(self.model, self.consistent.inertial)
        for value, name in zip(self.consistent.extra, self.consistent_extra_names()):
            joint, term = name.rsplit(".", 1)
            if term == "armature" and joint in self.joint_terms:          # a motor's rotor inertia is no joint's
                out.armature[velocity_index(out, joint)] = value
        return out

    def consistent_extra_names(self) -> list[str]:
        """Names of the extra terms (friction, offsets, rotor inertias, ...), in `consistent.extra` order."""
        return self.ols.selection.names[10 * (self.model.njoints - 1):]

    def mass_std(self) -> np.ndarray:
        """Standard error of each body's mass in the consistent fit (kg)."""
        return self.consistent_std[:self.consistent.inertial.size:10]


def identify_log(model: pin.Model, parts: list[LogPart], recorded: list[str], options: IdentifyOptions,
                 bounds: list[BodyBound] | None = None, notes: list[str] | None = None,
                 channels: Channels | None = None) -> IdentifyResult:
    """Identify `model`'s inertial parameters and joint terms from the logs `parts` (module docstring).
    recorded: the joints whose torque was logged, in model order (each part's tau in that order), when
    `channels` is None; channels: the rows (channels.py; with a transmission, the logged motors, each part's tau
    in their order); bounds: the plausibility bounds per body (plausible_bounds.body_bounds), None for none;
    notes: input notes to carry into the result."""
    cfg = options
    channels = channels or Channels.of_joints(model, recorded)
    recorded = list(channels.names)
    nr = len(recorded)
    candidates = [c for c in cfg.candidate_terms if c != "delay"]
    allowed, dropped = channels.joint_terms(model, tuple(dict.fromkeys(cfg.terms + tuple(candidates))))
    notes = list(notes or []) + dropped
    prepared = prepare_parts(model, parts, channels, cfg.signal, allowed, cfg.coulomb_width)
    first = prepared[0].processed
    edge = cfg.signal.edge_periods
    first.choices.append(f"training samples within {edge / first.cutoff_hz:.3g} s ({edge:g} cut-off periods) of a "
                         "validation window left out of the fit: the zero-phase filter would carry its data into them")
    n_train = sum(int(p.train.sum()) for p in prepared)
    if n_train < 10:
        raise InputError(f"after filtering, {n_train} training samples remain; widen the windows", source=cfg.source,
                         field="windows.train")
    inflation = max(filtered_noise_inflation(p.processed.cutoff_hz, p.processed.fs_raw, cfg.signal.order,
                                             p.processed.decimation) for p in prepared)
    full_train = stack([p.regressor.samples(p.train) for p in prepared])

    def tau_train(delays):
        return np.concatenate([p.torque(p.train, delays) for p in prepared])

    motor_names = [f"{m}.{k}" for m in (recorded if channels.motors else []) for k in channels.motor_terms]

    def names_for(terms: dict[str, tuple[str, ...]]) -> list[str]:
        return [f"{j}.{k}" for j in terms for k in term_columns(terms[j])] + motor_names

    joint_terms = {model.names[_joint_of(model, j)]: tuple(t for t in cfg.terms if t in allowed[j]) for j in allowed}
    candidate_pairs = [(model.names[_joint_of(model, j)], c) for j in allowed for c in candidates if c in allowed[j]]
    delays = np.zeros(nr)
    fit = fits_of_one_log(inflation)
    ols = fit(full_train.columns(names_for(joint_terms)), tau_train(delays))
    if ols.selection.rank == 0:
        raise InputError("the training window identifies no parameter", source=cfg.source, field="windows.train")
    tests, delays = _choose_terms(cfg, prepared, full_train, recorded, candidate_pairs, joint_terms, names_for,
                                  tau_train, fit)
    names = names_for(joint_terms)
    reg_train = full_train.columns(names)
    tau_tr = tau_train(delays)
    ols = fit(reg_train, tau_tr)
    cad = parameter_vector(model)
    body_names = [model.names[j] for j in range(1, model.njoints)]
    linear = linear_bounds(bounds, len(body_names), {n: i for i, n in enumerate(body_names)}) if bounds else None
    rss_ols, noise_unit = _noise_scale(reg_train, tau_tr, ols)
    bound95 = chi2_quantile(0.95, ols.selection.rank)
    grid_fits = {}          # the within-noise rules' fits on the training data, one per lambda of the grid
    if cfg.prior_rule == "holdout":
        prior = _holdout_choice(cfg, prepared, names, delays, ols.sigma, cad, linear)
    else:
        prior = within_noise_choice(reg_train, tau_tr, ols.sigma, cad, cfg.prior_grid,
                                    rss_ols if cfg.prior_rule == "within_noise" else None, noise_unit, bound95, linear,
                                    grid_fits)
    consistent = grid_fits.get(prior.chosen) or fit_consistent(reg_train, tau_tr, ols.sigma, cad, prior.chosen,
                                                                bounds=linear)
    std = consistent.std(rss_ols / ols.dof * ols.inflation)
    checks = [(p, p.check) for p in prepared if p.check.any()]
    reg_check = stack([p.regressor.samples(m) for p, m in checks]).columns(names) if checks else None
    predict = {"cad": lambda reg: (reg.X[:, :reg.n_inertial] @ cad).reshape(-1, nr),
               "ols": ols.predict, "consistent": consistent.predict}
    training_rms = {k: np.sqrt(np.mean((f(reg_train) - tau_tr) ** 2, axis=0)).tolist() for k, f in predict.items()}
    validation, t_range, curves, wrench = {}, [], {}, {}
    if checks:
        measured = np.concatenate([p.torque(m, delays) for p, m in checks])
        logged = np.concatenate([p.logged(m, delays) for p, m in checks])
        validation, t_range, curves = validate(predict, reg_check, measured, logged)
        joint_names, joint_idx, to_joints = channels.joint_map(model)
        if channels.motors:                 # the motors' errors mapped to the joints they determine
            for k in MODELS:
                errors = np.sqrt(np.mean(((curves[k] - measured) @ to_joints) ** 2, axis=0))
                validation[k]["rmse_joints"] = dict(zip(joint_names, errors.tolist()))
        curves["t"] = np.concatenate([p.t[m] for p, m in checks])
        q_check = np.concatenate([p.processed.decimated(p.processed.q)[m] for p, m in checks])
        if joint_idx:                      # joint torques the channels determine (all with joint channels)
            joint = (lambda x: x @ to_joints) if channels.motors else (lambda x: x)
            wrench = wrench_rms(cfg.wrench_frame, cfg.source, model, q_check, joint_idx,
                                {k: joint(curves[k]) for k in MODELS}, joint(measured))
    consistency = {b: (float(np.linalg.eigvalsh(pseudo_inertia(p))[0]), is_physically_consistent(p))
                   for b, p in zip(body_names, consistent.inertial.reshape(-1, 10))}
    within = _within_noise(reg_train, tau_tr, ols, consistent, base_values_of(ols.selection, consistent.params),
                           rss_ols, noise_unit)
    # what the data push against: the constraints' costs in the fit with the weakest prior of the grid (the
    # constraints alone; the chosen prior's own pull is not the data's), the same fit when it was chosen
    weakest = consistent if prior.chosen == min(cfg.prior_grid) else grid_fits.get(float(min(cfg.prior_grid))) or \
        fit_consistent(reg_train, tau_tr, ols.sigma, cad, min(cfg.prior_grid), bounds=linear)
    costs = constraint_costs(reg_train, tau_tr, ols.sigma, cad, weakest, body_names, noise_unit, linear)
    return IdentifyResult(options, model, recorded, prepared, joint_terms, delays, tests, ols, consistent, std, prior,
                          list(bounds or []), consistency, validation, training_rms, t_range, within, wrench, curves,
                          costs, {"train": reg_train, **({"check": reg_check} if checks else {})}, notes,
                          prepared[0].coulomb_width, channels, prepared[0].motor_width)


def _joint_of(model: pin.Model, idx_v: int) -> int:
    return next(j for j in range(1, model.njoints) if model.joints[j].idx_v == idx_v)


def fits_of_one_log(inflation: float):
    """fit_base for the regressors of one identification (all columns of one full regressor, named), each
    (columns, torques) pair fitted once: the first fit, the term tests' rounds, the delay search and the final fit
    often ask for the same one (all five on the shipped TIAGo log, which keeps no term and no delay)."""
    done: dict[tuple, BaseFit] = {}

    def fit(reg: Regressor, tau: np.ndarray) -> BaseFit:
        key = (tuple(reg.names), np.ascontiguousarray(tau, float).tobytes())
        if key not in done:
            done[key] = fit_base(reg, tau, inflation=inflation)
        return done[key]
    return fit


def _choose_terms(cfg, prepared, full_train, recorded, pairs, joint_terms, names_for, tau_train, fit):
    """term_selection.py's tests, in an order that keeps one term's misfit from passing for another's: the
    added columns with no delay, then the delays in the model with the columns found, then the columns again
    with those delays (their final decision). pairs: (joint, candidate) tried; recorded: the channels (a delay
    each). Adds the kept terms to joint_terms; (tests, delays)."""
    delays = np.zeros(len(recorded))
    columns = {(j, c): full_train.X[:, full_train.names.index(f"{j}.{ADDED_COLUMN[c]}")] for j, c in pairs}

    def column_tests(delays):
        """Forward selection: the candidate with the largest statistic joins the model while it passes; the
        others are tested again against the enlarged model (two candidates explaining one effect, e.g. Coulomb
        and viscous asymmetry on one joint, do not both pass)."""
        terms, result, remaining = dict(joint_terms), {}, list(pairs)
        while remaining:
            reg = full_train.columns(names_for(terms))
            base = fit(reg, tau_train(delays))
            projector, weights, unit = _projector(reg, base, tau_train(delays))
            round_ = added_column_tests(projector, weights, tau_train(delays).reshape(-1), remaining, columns, unit,
                                        len(pairs))
            result.update({(t.joint, t.term): t for t in round_})
            best = max(round_, key=lambda t: t.statistic)
            if not best.kept:
                break
            terms[best.joint] += (best.term,)
            remaining.remove((best.joint, best.term))
        for t in result.values():           # kept: joined the model (a later round's test of it is not run)
            t.kept = (t.joint, t.term) not in remaining
        return [result[p] for p in pairs]

    found = column_tests(delays) if pairs else []
    tests: list[TermTest] = []
    if "delay" in cfg.candidate_terms:
        with_found = {j: t + tuple(f.term for f in found if f.kept and f.joint == j) for j, t in joint_terms.items()}
        reg = full_train.columns(names_for(with_found))
        base = fit(reg, tau_train(delays))
        projector, weights, unit = _projector(reg, base, tau_train(delays))
        unshifted = tau_train(delays)

        def torque_at(k, d):
            out = unshifted.copy()
            if k is not None:
                out[:, k] = np.concatenate([p.torque_column(p.train, k, d) for p in prepared])
            return out

        step = 1.0 / prepared[0].processed.fs_raw
        tests += choose_delays(projector, weights, torque_at, recorded, delay_grid(step, cfg.delay_max_s), unit)
        delays = np.array([t.value if t.kept else 0.0 for t in tests])
        found = column_tests(delays) if pairs else []
    tests += found
    for t in found:
        if t.kept:
            joint_terms[t.joint] += (t.term,)
    return tests, delays


def _projector(reg: Regressor, ols: BaseFit, tau: np.ndarray) -> tuple[Projector, np.ndarray, float]:
    """The weighted base regressor's projector, the row weights and one noise unit (weighted cost)."""
    weights = row_weights(ols.sigma, len(tau))
    _, noise_unit = _noise_scale(reg, tau, ols)
    return Projector(reg.X[:, ols.selection.independent] * weights[:, None]), weights, noise_unit


def _holdout_choice(cfg: IdentifyOptions, prepared: list[PreparedPart], names: list[str], delays: np.ndarray,
                    sigma, cad, linear: LinearBounds | None) -> PriorWeightChoice:
    """prior_weight.holdout_choice on the training samples: the first prior_split of them (parts in order,
    each in time) fitted, the rest scored, the filter's reach left out between them in the part where they
    meet (the part that scores a weight is not seen by its fit)."""
    n_fit = int(round(cfg.prior_split * sum(int(p.train.sum()) for p in prepared)))
    fit_parts, score_parts, seen, gap = [], [], 0, 0.0
    for p in prepared:
        idx = np.flatnonzero(p.train)
        first, second = np.zeros_like(p.train), np.zeros_like(p.train)
        k = min(max(n_fit - seen, 0), len(idx))
        first[idx[:k]], second[idx[k:]] = True, True
        if 0 < k < len(idx):
            guard = cfg.signal.edge_periods / p.processed.cutoff_hz
            first &= p.t < p.t[idx[k]] - guard
            gap = float(p.t[idx[k]] - p.t[first].max()) if first.any() else 0.0
        seen += len(idx)
        fit_parts.append((p, first))
        score_parts.append((p, second))
    n1, n2 = sum(int(m.sum()) for _, m in fit_parts), sum(int(m.sum()) for _, m in score_parts)
    if n1 < 10 or n2 < 3:
        raise InputError(f"choosing the prior weight leaves {n1} samples to fit and {n2} to score (model.prior_split "
                         f"{cfg.prior_split:g}); widen the training window", source=cfg.source, field="windows.train")

    def rows(pairs):
        return (stack([p.regressor.samples(m) for p, m in pairs]).columns(names),
                np.concatenate([p.torque(m, delays) for p, m in pairs]))

    (reg1, tau1), (reg2, tau2) = rows(fit_parts), rows(score_parts)
    prior = holdout_choice(reg1, tau1, reg2, tau2, sigma, cad, cfg.prior_grid, cfg.prior_split, bounds=linear)
    prior.gap_s = gap
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
    (serial_correlation.py), against the chi-square 95 % quantile."""
    pred_ols, pred_fit = ols.predict(reg), fit.predict(reg)
    increase = (fit.data_cost - rss_ols) / (rss_ols / ols.dof)
    p = ols.selection.rank
    return {"distance_in_noise_units": increase / ols.inflation, "noise_inflation": ols.inflation,
            "noise_unit": noise_unit,
            "residual_increase_independent_rows": increase, "chi2_95": chi2_quantile(0.95, p),
            "base_parameters": p,
            "rms_ratio": (np.sqrt(np.mean((pred_fit - tau) ** 2, axis=0))
                          / np.sqrt(np.mean((pred_ols - tau) ** 2, axis=0))).tolist(),
            "max_base_deviation_in_std": float(np.max(np.abs(beta_c - ols.values) / ols.std))}
