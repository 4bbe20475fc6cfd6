"""Which set-up value reproduces a Monte-Carlo figure of the spec (docs/laser_psd.md, "Which set-up reproduces
each figure").

The spec's table of offset accuracies does not state every set-up choice behind it. For one figure (an
offset's sd) and one set-up variable (the others at their stated values), `crossings` scans the variable
over its physical range, finds every value at which robocal's linearised prediction equals the spec's
figure (a sign change of log(prediction / figure) between grid points, refined by Brent's method), and
keeps a value only if the prediction there is within `rtol` of the figure (a jump of the IK branch between
grid points is a sign change with no root). With no crossing, the figure is outside what that variable can
give: `FigureSearch.low` / `.high` are the range it spans. Each crossing carries all the design's predicted
figures at that value, to show what reproducing one figure does to the others.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import brentq

from robocal.errors import RobocalError


@dataclass
class Crossing:
    value: float               # the set-up value (the variable's own unit)
    figures: np.ndarray        # every predicted figure of the design there


@dataclass
class FigureSearch:
    target: float
    low: float                 # smallest and largest prediction of this figure over the grid
    high: float
    crossings: list[Crossing] = field(default_factory=list)
    unreachable: int = 0       # grid values at which the set-up could not be realised


class CachedEvaluation:
    """evaluate(x) -> predicted figures (or None when the set-up cannot be realised), computed once per x."""

    def __init__(self, evaluate: Callable[[float], np.ndarray]):
        self.evaluate, self.cache = evaluate, {}

    def __call__(self, x: float):
        x = float(x)
        if x not in self.cache:
            try:
                self.cache[x] = np.asarray(self.evaluate(x), dtype=float)
            except (RobocalError, np.linalg.LinAlgError):
                self.cache[x] = None
        return self.cache[x]


def crossings(evaluate: CachedEvaluation, grid, k: int, target: float, rtol: float = 0.01,
              xtol: float = 1e-6) -> FigureSearch:
    """Values of the variable on `grid` (ascending) at which figure k of evaluate(x) equals `target`."""
    grid = np.asarray(grid, dtype=float)
    values = [evaluate(x) for x in grid]
    ok = [v is not None for v in values]
    f = np.array([v[k] if v is not None else np.nan for v in values])
    out = FigureSearch(target, float(np.nanmin(f)), float(np.nanmax(f)), unreachable=int(len(grid) - sum(ok)))

    def g(x):
        v = evaluate(x)
        if v is None:
            raise RobocalError("unreachable inside a bracket")
        return np.log(v[k] / target)

    for a, b, fa, fb in zip(grid[:-1], grid[1:], f[:-1], f[1:]):
        if not (np.isfinite(fa) and np.isfinite(fb)) or (fa - target) * (fb - target) > 0:
            continue
        try:
            x = brentq(g, a, b, xtol=xtol) if fa != target else a
        except (RobocalError, ValueError):
            continue
        v = evaluate(x)
        if v is not None and abs(v[k] / target - 1) <= rtol:
            out.crossings.append(Crossing(float(x), v))
    return out


def within(figures: np.ndarray, spec: np.ndarray, band: float = 0.25) -> int:
    """How many figures are within +-band (relative) of the spec's."""
    return int(np.sum(np.abs(np.asarray(figures) / np.asarray(spec) - 1) <= band))
