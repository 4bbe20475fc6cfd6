"""Model selection: a ladder of models from one config, chosen by cross-validated error (docs/validation.md).

The ladder, simplest first: registration only (preset none), joint offsets, the full geometric set, then the
full set plus each non-geometric kind the config itself asks for (compliance, backlash, tilt), added one at a
time in that order. Every rung is cross-validated on the same folds; the choice follows the
one-standard-error rule: the simplest rung whose held-out norm RMS is within one standard error of the best.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robocal.estimation.cross_validation import CVTable

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

    def table(self) -> list[str]:
        unit = next((r.cv.unit for r in self.rungs if r.cv), "mm")
        lines = [f"Model ladder, {self.folds}: RMS of the error norm ({unit}) on held-out samples",
                 "free: parameters the rung frees (before the identifiability selection)",
                 f"{'':2}{'model':<34}{'free':>7}{'train RMS':>11}{'held-out RMS':>14}{'+- s.e.':>9}"]
        for k, r in enumerate(self.rungs):
            mark = "*" if k == self.chosen else ("b" if k == self.best else " ")
            if r.cv is None:
                lines.append(f"{mark:<2}{r.name:<34}{'':>7}  skipped: {r.skipped}")
                continue
            lines.append(f"{mark:<2}{r.name:<34}{r.n_free:>7}{r.cv.train_rms:>11.4g}{r.cv.rms:>14.4g}"
                         f"{r.cv.stderr:>9.2g}")
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
