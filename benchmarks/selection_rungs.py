"""One rung of a model ladder, fitted on one session: every selection criterion, and its error on other sessions.

Used by benchmarks/selection_study.py (the real TIAGo sessions and the simulated robots). A rung is a config
(one measurement choice) with its `parameters` section overridden and a prior setting:
- criteria from the fitting session alone: the training RMS, leave-one-out and K-fold cross-validation by brute
  force (robocal.estimation.cross_validate), the closed-form leave-one-out of the linearised fit, GCV, Akaike's
  final prediction error (the expected error at the same postures with new noise; AIC's target), AIC, BIC and
  the evidence of the linearised Gaussian model (robocal.estimation.model_criteria);
- targets: the error of the fitted model on another session, its registration frames kept from the fit
  ("kept") or refitted on that session with every robot parameter held ("refit").
All errors are the norm RMS of one point (`point`, default the first point of the scored block), in mm.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from robocal import calibrate
from robocal.estimation import cross_validate, kfold, term_errors
from robocal.estimation import model_criteria as mc
from robocal.estimation.physical_scale import is_registration, measured_frames
from robocal.estimation.registration import fit_subset
from robocal.estimation.session_holdout import held_out_figure
from robocal.workflows import setup_for_data

CRITERIA = ("train", "loo", "kfold", "aloo", "aloo_in", "aloo_median", "gcv", "fpe", "aic", "bic", "evidence", "loso")
LOWER_IS_BETTER = {c: c != "evidence" for c in CRITERIA}


@dataclass
class Rung:
    label: str
    measurement: str             # key of the config (e.g. "point", "hand")
    parameters: dict             # merged into the config's `parameters`
    prior: str                   # "none" | "auto" | "evidence" (the evidence's prior, always applied) |
                                 # "strength X" (sigma = X physical scales) | a label of explicit priors

    @property
    def regularisation(self) -> str:
        return "auto" if self.prior == "auto" or self.strength is not None else "none"

    @property
    def strength(self) -> float | None:
        """The given prior strength of a "strength X" rung (robocal's prior_strength option)."""
        return float(self.prior.split()[1]) if self.prior.startswith("strength") else None


@dataclass
class Scored:
    rung: Rung
    n_free: int = 0
    status: str = ""
    values: dict = field(default_factory=dict)     # criterion -> value
    targets: dict = field(default_factory=dict)    # "<session> kept" / "<session> refit" -> mm
    seconds: float = 0.0


def _setup(config, csv, rung: Rung):
    s = setup_for_data(config, csv, rung.parameters)
    s.options.regularisation = rung.regularisation
    s.options.prior_strength = rung.strength
    return s


def registration_names(problem) -> list[str]:
    measured = measured_frames(problem)
    return [p.name for p in problem.params if p.kind == "base" or
            (p.vary and is_registration(p, measured) and p.kind != "auxiliary")]


def other_session(config, csv, rung: Rung, fitted, block: str, point) -> dict:
    """Error of the fitted parameters on another session: registration kept, and the base refitted there."""
    s = _setup(config, csv, rung)
    for p in s.problem.params:
        if p.name in fitted:
            p.value = fitted[p.name].value
    kept = term_errors(s.problem)[block].point_stats(point).rmse_norm
    base = [n for n in registration_names(s.problem) if n.startswith("base.")]
    fit_subset(s.problem, base, s.options)
    return {"kept": kept, "refit": term_errors(s.problem)[block].point_stats(point).rmse_norm}


def score(config, train_csv, rung: Rung, others: dict, point=0, k: int = 5, loo: bool = True,
          cross_fit: dict | None = None) -> Scored:
    """Fit `rung` on `train_csv`, compute every criterion, score it on each of `others` ({name: csv}).
    cross_fit: {name: csv} of a second session: leave-one-session-out over the two (each fitted, scored on the
    other with its tracker frame refitted; RMS of the two)."""
    t0 = time.perf_counter()
    fresh = _setup(config, train_csv, rung)
    # the evidence scores a model with a proper prior on every robot parameter: none for a rung without one
    ev = mc.nominal_evidence(fresh.problem, fresh.options) if rung.prior != "none" else None
    if rung.prior == "evidence":      # the evidence's own model: its prior on every robot parameter, always
        rung = replace(rung, prior=f"strength {ev.strength:.6g}")
    out = Scored(rung)
    s = _setup(config, train_csv, rung)
    block = s.problem.residuals[0].name
    res = calibrate(s.problem, s.options)
    out.n_free, out.status = len(res.params.free_names), res.status
    lin = mc.linearise(s.problem)
    part = point if isinstance(point, int) else s.problem.residuals[0].labels.index(point)
    _, train = mc.norms(lin, lin.r[lin.data] / lin.scale[lin.data], block=block, part=part)
    held = mc.approximate_loo(lin)
    smp, aloo = mc.norms(lin, held.raw, block=block, part=part)
    inside = mc.inside_others(s.problem.values)[smp]
    ic = mc.information_criteria(lin)
    n = len(s.problem.values)
    v = {"train": mc.rms(train), "aloo": mc.rms(aloo), "aloo_in": mc.rms(aloo[inside]),
         "aloo_in_se": held_out_figure(aloo[inside])[1], "aloo_se": held_out_figure(aloo)[1],
         "aloo_median": float(np.median(aloo)), "gcv": mc.rms(train) * np.sqrt(ic.gcv),
         "fpe": mc.rms(train) * np.sqrt(ic.fpe), "aic": ic.aic, "bic": ic.bic,
         "evidence": ev.log_evidence if ev else float("nan"), "evidence_strength": ev.strength if ev else None,
         "p_eff": ic.parameters, "aloo_undetermined": len(held.undetermined)}
    for name, folds in (("kfold", kfold(n, k) if k else None), ("loo", kfold(n, n) if loo else None)):
        if folds is None:
            continue
        cvs = _setup(config, train_csv, rung)
        v[name] = cross_validate(cvs.problem, folds, cvs.options, scored=[block]).point_stats(block, point).rmse_norm
    for name, csv in (cross_fit or {}).items():      # leave-one-session-out over this session and `csv`
        s2 = _setup(config, csv, rung)
        calibrate(s2.problem, s2.options)
        there = other_session(config, train_csv, rung, s2.problem.params, block, point)["refit"]
        here = other_session(config, csv, rung, s.problem.params, block, point)["refit"]
        v["loso"] = float(np.sqrt((there ** 2 + here ** 2) / 2))
    out.values = v
    for name, csv in others.items():
        for how, e in other_session(config, csv, rung, s.problem.params, block, point).items():
            out.targets[f"{name} {how}"] = e
    out.seconds = time.perf_counter() - t0
    return out


def choice(scored: list[Scored], criterion: str) -> int | None:
    """Index of the rung a criterion picks (lowest, or highest evidence); None if no rung has it."""
    vals = np.array([s.values.get(criterion, np.nan) for s in scored], float)
    if not np.any(np.isfinite(vals)):
        return None
    vals = np.where(np.isfinite(vals), vals, np.inf if LOWER_IS_BETTER.get(criterion, True) else -np.inf)
    return int(np.argmin(vals) if LOWER_IS_BETTER.get(criterion, True) else np.argmax(vals))
