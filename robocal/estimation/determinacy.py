"""How well the data determine each parameter and each direction: one set of classes, used everywhere.

Every requested parameter falls in exactly one class (the summary, result.json and report.html count these):

  determined         identifiable from the data alone; data-only standard error within its threshold
                     (0.1 mm, 0.1 mrad, settable: solver.determined_length / determined_angle)
  weakly determined  identifiable from the data alone; data-only standard error within its physical scale
                     (robocal.estimation.physical_scale; a registration frame has none: any finite error)
  loose              identifiable from the data alone, but its data-only standard error exceeds its physical
                     scale: the data see it less well than physics knows it (its prior, if any, has the say)
  set by the prior   not identifiable from the data (confounded with other parameters), kept because a prior
                     (the config's or the default one) decides it
  fixed              not identifiable from the data and without a prior: held at its initial value

"Data-only" standard error: from the data rows alone at the measured noise, the parameters set by the prior
held at their values (what a fit without any prior would give); the fit's own standard error adds the prior's
contribution. Numerical rank alone says nothing about how well: a condition number of 1e4 can leave a joint
offset free to wander by a radian.

Directions: the eigenvectors of the data-only covariance of the identifiable parameters, in threshold units,
whose standard error exceeds the threshold, each written as its largest parameter coefficients.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DETERMINED, WEAK, LOOSE, PRIOR_ONLY, FIXED = "determined", "weakly determined", "loose", "set by the prior", "fixed"
CLASSES = (DETERMINED, WEAK, LOOSE, PRIOR_ONLY, FIXED)
DATA_CLASSES = (DETERMINED, WEAK, LOOSE)           # identifiable from the data alone
MEANING = {
    DETERMINED: "identifiable from the data alone, data-only standard error within the threshold "
                "(solver.determined_length / determined_angle)",
    WEAK: "identifiable from the data alone, data-only standard error within its physical scale",
    LOOSE: "identifiable from the data alone, data-only standard error beyond its physical scale",
    PRIOR_ONLY: "not identifiable from the data (confounded with other parameters): its prior sets it",
    FIXED: "not identifiable from the data and no prior: held at its initial value",
}
NULL_TOL = 1e-12       # relative eigenvalue below which a direction carries no information at all
MAX_TERMS = 4          # parameters named per direction in words
PARTICIPATES = 0.1     # share of a direction's largest coefficient that makes a parameter part of it


@dataclass
class Direction:
    terms: list[tuple[str, float]]       # (parameter, coefficient) of the unit direction in threshold units,
                                         # every parameter taking part (PARTICIPATES), largest first
    stderr: float                        # in thresholds (1 = at the threshold)
    beyond_scale: bool                   # the data know it less well than physics does
    decided_by_prior: bool = False
    in_scales: float = 0.0               # its standard error in physical scales of the parameters it moves

    def describe(self) -> str:
        shown = self.terms[:MAX_TERMS]
        combo = " ".join(f"{c:+.2f} {n}" for n, c in shown)
        more = f" (+{len(self.terms) - len(shown)} smaller terms)" if len(self.terms) > len(shown) else ""
        level = LOOSE + " (beyond its physical scale)" if self.beyond_scale else WEAK
        se = "no information" if not np.isfinite(self.stderr) else f"standard error {self.stderr:.3g} x threshold"
        who = "; its prior decides it" if self.decided_by_prior else ""
        return f"{combo}{more}: {level} ({se}){who}"


@dataclass
class Determinacy:
    stderr: dict[str, float]                      # data-only standard error, SI (inf: the data cannot tell)
    classes: dict[str, str]                       # every requested parameter: one of CLASSES
    directions: list[Direction] = field(default_factory=list)    # weakest first, every one above threshold

    def names_in(self, cls: str) -> list[str]:
        return [n for n, c in self.classes.items() if c == cls]

    def counts(self) -> dict[str, int]:
        return {c: len(self.names_in(c)) for c in CLASSES}

    @property
    def identifiable(self) -> int:
        """Parameters identifiable from the data alone."""
        return sum(len(self.names_in(c)) for c in DATA_CLASSES)

    def to_dict(self) -> dict:
        return {"counts": self.counts(), "meaning": MEANING, "classes": self.classes,
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
             prior_only: list[str], fixed: list[str], with_prior: set[str]) -> Determinacy:
    """Classes of `names`, the parameters the data can identify (columns of J_data, the data rows), plus the
    ones the data cannot: `prior_only` (kept by their prior) and `fixed` (held at their initial value)."""
    # a parameter without a physical threshold (a screw lead, a ratio) is measured in what one sigma of data sees
    colnorm = np.linalg.norm(J_data, axis=0)
    thresholds = np.where(np.isfinite(thresholds), thresholds, 1.0 / np.where(colnorm > 0, colnorm, 1.0))
    se_t, cov_eig, V = data_only_stderr(J_data, noise2, thresholds)
    stderr, classes = {}, {}
    for n, s, t, sc in zip(names, se_t, thresholds, scales):
        stderr[n] = float(s * t)
        classes[n] = DETERMINED if s <= 1.0 else (WEAK if s * t <= sc else LOOSE)
    for group, cls in ((prior_only, PRIOR_ONLY), (fixed, FIXED)):
        for n in group:
            stderr[n], classes[n] = float("inf"), cls
    directions = []
    ratio = scales / thresholds          # the physical scale in thresholds, per column
    finite = np.isfinite(ratio)
    ratio2 = np.where(finite, ratio, np.inf) ** 2
    by_eig = np.argsort(-cov_eig)
    wide = by_eig[:int(np.sum(np.sqrt(cov_eig) > 1.0))] if len(cov_eig) else by_eig     # weakest first
    Vw = np.ascontiguousarray(V[:, wide].T)          # one direction a row: the arrays below at once
    A = np.abs(Vw)
    by_size = np.argsort(-A, axis=1)
    largest = A.max(axis=1) if len(wide) else np.zeros(0)
    # beyond scale: the direction's spread exceeds the physical scale of the parameters it moves
    reach = np.sqrt(np.sum((Vw ** 2) / ratio2, axis=1))
    for row, k in enumerate(wide):
        se = float(np.sqrt(cov_eig[k]))
        v, a, size_order = Vw[row], A[row], by_size[row]
        order = size_order[a[size_order] > PARTICIPATES * largest[row]].tolist()
        sign = np.sign(v[order[0]]) or 1.0
        terms = list(zip([names[i] for i in order], (sign * v[order]).tolist()))
        r = float(reach[row])
        beyond = se * r > 1.0 if r > 0 else False
        # the prior decides it when every parameter of it with a physical scale has one (registration frames
        # have neither: the prior holds them through the robot parameters they are tied to)
        scaled = [i for i in order if finite[i]]
        prior = beyond and bool(scaled) and all(names[i] in with_prior for i in scaled)
        directions.append(Direction(terms, se, bool(beyond), prior, se * r))
    return Determinacy(stderr, classes, directions)
