"""Model selection: a ladder of models from one config, chosen by held-out error (docs/validation.md).

The ladder, simplest first: registration only (preset none), joint offsets, the full geometric set, then the
full set plus each non-geometric kind the config itself asks for (compliance, backlash, tilt), added one at a
time in that order. Every rung is scored on held-out data; the choice follows the one-standard-error rule: the
simplest rung whose held-out norm RMS is within one standard error of the best.

The held-out figure `robocal select` uses (docs/validation.md "Choosing a model", and the study behind it):
with two or more sessions, leave-one-session-out (each session predicted by the robot fitted jointly on the
others, its per-session frames registered there: robocal.estimation.cross_validation.cv_table on session folds);
with one session, the closed-form leave-one-out by posture of each rung's linearised fit (`closed_form_cv`: no
refits), each rung at the prior `calibrate` chooses for it. The study also tried choosing each rung's prior
strength on a grid by the same figure: rejected by the TIAGo sessions (docs/validation.md); that rule lives
with the study, in benchmarks/strength_rule.py.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robocal.estimation.cross_validation import CVTable
from robocal.estimation.model_criteria import approximate_loo, linearise, norms
from robocal.estimation.problem import Problem
from robocal.estimation.session_holdout import held_out_figure

EXTRA_KINDS = ("compliance", "backlash", "tilt")


@dataclass
class Rung:
    name: str
    parameters: dict               # merged into the config's `parameters` section
    n_free: int = 0
    cv: CVTable | None = None
    skipped: str = ""              # why the rung could not be fitted

    def to_dict(self) -> dict:
        return {"name": self.name, "parameters": self.parameters, "free_parameters": self.n_free,
                "cv": self.cv.to_dict() if self.cv else None, "skipped": self.skipped or None}


@dataclass
class Selection:
    rungs: list[Rung]
    chosen: int
    best: int
    folds: str
    rule: str = "one-standard-error rule: the simplest model within one standard error of the lowest held-out RMS"
    notes: list[str] = field(default_factory=list)
    fits: dict = field(default_factory=dict, repr=False)   # rung index -> (setup, nominal, result) of its full fit
    camera_cache: dict = field(default_factory=dict, repr=False)   # camera set-ups' solutions, for the final fit

    def table(self) -> list[str]:
        unit = next((r.cv.unit for r in self.rungs if r.cv), "mm")
        others = next((list(r.cv.others) for r in self.rungs if r.cv and r.cv.others), [])
        lines = [f"Model ladder, {self.folds}: RMS of the error norm ({unit}) on held-out samples"
                 + (f"; orientation of pose blocks: train / held-out ({', '.join(others)})" if others else ""),
                 "free: parameters the rung frees (before the identifiability selection)",
                 f"{'':2}{'model':<34}{'free':>7}{'train RMS':>11}{'held-out RMS':>14}{'+- s.e.':>9}"]
        for k, r in enumerate(self.rungs):
            mark = "*" if k == self.chosen else ("b" if k == self.best else " ")
            if r.cv is None:
                lines.append(f"{mark:<2}{r.name:<34}{'':>7}  skipped: {r.skipped}")
                continue
            line = f"{mark:<2}{r.name:<34}{r.n_free:>7}{r.cv.train_rms:>11.4g}{r.cv.rms:>14.4g}{r.cv.stderr:>9.2g}"
            for u, v in r.cv.others.items():        # orientation of pose blocks
                line += f"   {v['train']:.4g} / {v['rms']:.4g} +- {v['stderr']:.2g} {u}"
            lines.append(line)
        lines.append(f"* chosen ({self.rule}); b lowest held-out RMS")
        return lines

    def to_dict(self) -> dict:
        return {"folds": self.folds, "rule": self.rule, "chosen": self.rungs[self.chosen].name,
                "lowest": self.rungs[self.best].name, "ladder": [r.to_dict() for r in self.rungs]}


def ladder(raw_parameters: dict | None) -> list[Rung]:
    """The rungs for a config's `parameters` section."""
    base = {"compliance": False, "backlash": False, "tilt": False}
    rungs = [Rung("registration", {**base, "preset": "none"}), Rung("joint offsets", {**base, "preset": "offsets"}),
             Rung("full geometric", {**base, "preset": "full"})]
    extra = dict(base)
    for kind in EXTRA_KINDS:
        value = (raw_parameters or {}).get(kind)
        if value:
            extra = {**extra, kind: value}
            rungs.append(Rung("full + " + " + ".join(k for k in EXTRA_KINDS if extra[k]), {**extra, "preset": "full"}))
    return rungs


def one_standard_error(rms: np.ndarray, stderr: np.ndarray) -> tuple[int, int]:
    """(chosen, best) indices: the first (simplest) entry within one standard error of the lowest."""
    best = int(np.nanargmin(rms))
    limit = rms[best] + (stderr[best] if np.isfinite(stderr[best]) else 0.0)
    chosen = next(k for k in range(len(rms)) if np.isfinite(rms[k]) and rms[k] <= limit)
    return chosen, best


def closed_form_cv(problem: Problem, folds: list[np.ndarray]) -> CVTable:
    """The closed-form leave-one-out of a fitted problem over `folds` (whole postures) as a CV table: held-out
    and training RMS of the error norm (mm for points; mrad of pose blocks as a second unit; px of image points)
    with the held-out standard error over the points (no refits)."""
    lin = linearise(problem)
    raw = approximate_loo(lin, folds).raw
    raw = np.where(np.isnan(raw), np.inf, raw)
    fitted_raw = lin.r[lin.data] / lin.scale[lin.data]      # the fit's own SI residual of every data row
    figures = {}
    for kind, unit in (("length", "mm"), ("angle", "mrad"), ("pixel", "px")):
        if not np.any(lin.data & (lin.kind == kind)):
            continue
        _, held = norms(lin, raw, kind)
        _, fitted = norms(lin, fitted_raw, kind)
        rms, se = held_out_figure(held)
        figures[unit] = (rms, se, float(np.sqrt(np.mean(fitted ** 2))) if len(fitted) else float("nan"))
    unit = next(iter(figures))
    rms, se, tr = figures.pop(unit)
    return CVTable(unit, [], rms, se, tr, {u: {"rms": a, "stderr": b, "train": c} for u, (a, b, c) in figures.items()})
