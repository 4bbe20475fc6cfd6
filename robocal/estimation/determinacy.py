"""How well the data determine each parameter and each direction, against physical thresholds.

A parameter is determined when its data-only standard error at the measured noise is below its threshold
(0.1 mm, 0.1 mrad, settable: solver.determined_length / determined_angle), weakly determined when it is
below its physical scale (robocal.estimation.physical_scale), not determined beyond that or when the data
cannot separate it at all (structurally confounded: fixed at nominal). Numerical rank alone says nothing
about this: a condition number of 1e4 can leave a joint offset free to wander by a radian.

Directions: the eigenvectors of the data-only covariance, in threshold units, whose standard error exceeds
the threshold, each written as its largest parameter coefficients (docs/validation.md).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DETERMINED, WEAK, NOT_DETERMINED = "determined", "weakly determined", "not determined"
NULL_TOL = 1e-12       # relative eigenvalue below which a direction carries no information at all
MAX_DIRECTIONS = 6     # weakest directions listed in words
MAX_TERMS = 4          # parameters named per direction


@dataclass
class Direction:
    terms: list[tuple[str, float]]       # (parameter, coefficient) of the unit direction in threshold units
    stderr: float                        # in thresholds (1 = at the threshold)
    beyond_scale: bool                   # the data know it less well than physics does
    decided_by_prior: bool = False
    in_scales: float = 0.0               # its standard error in physical scales of the parameters it moves

    def describe(self) -> str:
        combo = " ".join(f"{c:+.2f} {n}" for n, c in self.terms)
        level = "not determined" if self.beyond_scale else "weakly determined"
        se = "no information" if not np.isfinite(self.stderr) else f"standard error {self.stderr:.3g} x threshold"
        who = "; the prior decided it, not the data" if self.decided_by_prior else ""
        return f"{combo}: {level} ({se}){who}"


@dataclass
class Determinacy:
    stderr: dict[str, float]                      # data-only standard error, SI
    classes: dict[str, str]
    directions: list[Direction] = field(default_factory=list)

    def names_in(self, cls: str) -> list[str]:
        return [n for n, c in self.classes.items() if c == cls]

    def to_dict(self) -> dict:
        return {"classes": self.classes,
                "data_only_stderr": {n: (v if np.isfinite(v) else None) for n, v in self.stderr.items()},
                "weak_directions": [d.describe() for d in self.directions]}


def data_only_stderr(J: np.ndarray, noise2: float, units: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(stderr in `units`, variance of each principal direction in `units`, directions) from data rows J (m, n).

    units: a positive unit per column (its threshold, SI): a parameter of u units moves by u * units. Computed
    from the SVD of the scaled J (not J^T J, which squares the condition); directions with a singular value at
    the rounding level carry no information and get infinite variance."""
    Jt = J * units[None, :]
    if not Jt.size:
        return np.zeros(J.shape[1]), np.zeros(0), np.zeros((J.shape[1], 0))
    _, sv, Vt = np.linalg.svd(Jt, full_matrices=False)
    V = Vt.T
    tiny = sv <= NULL_TOL * max(sv.max(), 1e-300)
    inv = np.where(tiny, np.inf, noise2 / np.where(tiny, 1.0, sv) ** 2)
    with np.errstate(invalid="ignore"):
        var = np.where((V ** 2 > 1e-12) & np.isinf(inv)[None, :], np.inf, V ** 2 * np.where(tiny, 0.0, inv)).sum(1)
    if V.shape[1] < J.shape[1]:     # fewer rows than columns: the rest of the space is unseen
        var[:] = np.where(np.linalg.norm(V, axis=1) < 1 - 1e-9, np.inf, var)
    return np.sqrt(var), inv, V


def classify(names, J_data: np.ndarray, noise2: float, thresholds: np.ndarray, scales: np.ndarray,
             dependent: list[str], with_prior: set[str]) -> Determinacy:
    """Classes of the free columns `names` of J_data, plus the structurally `dependent` ones (not determined)."""
    # a parameter without a physical threshold (a screw lead, a ratio) is measured in what one sigma of data sees
    colnorm = np.linalg.norm(J_data, axis=0)
    thresholds = np.where(np.isfinite(thresholds), thresholds, 1.0 / np.where(colnorm > 0, colnorm, 1.0))
    se_t, cov_eig, V = data_only_stderr(J_data, noise2, thresholds)
    stderr, classes = {}, {}
    for n, s, t, sc in zip(names, se_t, thresholds, scales):
        stderr[n] = float(s * t)
        classes[n] = DETERMINED if s <= 1.0 else (WEAK if s * t <= sc else NOT_DETERMINED)
    for n in dependent:
        stderr[n], classes[n] = float("inf"), NOT_DETERMINED
    directions = []
    ratio = scales / thresholds          # the physical scale in thresholds, per column
    for k in np.argsort(-cov_eig):
        se = float(np.sqrt(cov_eig[k]))
        if se <= 1.0 or len(directions) >= MAX_DIRECTIONS:
            break
        v = V[:, k]
        order = [i for i in np.argsort(-np.abs(v)) if abs(v[i]) > 0.1 * np.abs(v).max()][:MAX_TERMS]
        sign = np.sign(v[order[0]]) or 1.0
        terms = [(names[i], float(sign * v[i])) for i in order]
        # beyond scale: the direction's spread exceeds the physical scale of the parameters it moves
        reach = float(np.sqrt(np.sum((v ** 2) / np.where(np.isfinite(ratio), ratio, np.inf) ** 2)))
        beyond = se * reach > 1.0 if reach > 0 else False
        prior = beyond and all(names[i] in with_prior for i in order)
        directions.append(Direction(terms, se, bool(beyond), prior, se * reach))
    return Determinacy(stderr, classes, directions)
