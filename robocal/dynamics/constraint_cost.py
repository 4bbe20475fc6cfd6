"""Which physical constraints hold the consistent fit away from the unconstrained one.

When the consistent model predicts worse than OLS, the question is which constraint the data push
against: a body that cannot be a mass distribution with the inertia the data ask for, a friction
or rotor-inertia term the data want negative, a body the data want lighter or heavier than its mass band or
spread beyond its bounding ellipsoid (plausible_bounds.py). Each constraint active at the solution (a
body's pseudo-inertia PSD, a term's bound, a plausibility row; an inactive one costs nothing) is dropped in turn, the fit repeated at the same prior weight, and the fall of its objective
(weighted data cost plus prior; the data part alone may rise as the prior's pull is traded) reported
in the noise units of identify_run's within-noise test (residual increase over the unconstrained
fit's noise variance, divided by the filtered noise's variance inflation). A large cost on one constraint points at the
model (an unmodelled effect the inertias or that term absorb) or at the data, not at the solver.
A constraint is binding when the fit without it breaks it; only those are reported. The costs carry
the conic solver's tolerance and the projection onto the cones: a few tenths of a noise unit on the
TIAGo log (a binding constraint that costs nothing can come out slightly negative), so below
MEASURABLE_COST a cost is not read as one.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.dynamics.consistent_fit import NONNEGATIVE_TERMS, ConsistentFit, fit_consistent
from robocal.dynamics.inertial import pseudo_inertia
from robocal.dynamics.plausible_bounds import LinearBounds
from robocal.dynamics.regression import Regressor

#: noise units below which a cost is within the solver's tolerance (see above)
MEASURABLE_COST = 0.5
#: relative tolerance under which a constraint counts as active at the solution
ACTIVE = 1e-5
#: the same for the plausibility rows, whose slack the interior-point method leaves at ~1e-4 of the row's size
ACTIVE_ROWS = 1e-2
WORDS = {"body": "body of {j} realisable", "mass_min": "body of {j}: mass >= its band's low end",
         "mass_max": "body of {j}: mass <= its band's high end", "ellipsoid": "body of {j}: mass inside its ellipsoid"}


@dataclass
class ConstraintCost:
    """joint: the body's joint or the term's; kind: 'body' (its pseudo-inertia PSD), a plausibility row's
    (mass_min, mass_max, ellipsoid) or the term's kind (coulomb, viscous, armature, ...: >= 0); cost: fall of
    the fit's objective when it is dropped, in noise units; value_without: in the fit without it, the body's
    smallest pseudo-inertia eigenvalue (kg m^2), the body's mass (kg; mass rows), tr(Q J) (kg; ellipsoid,
    negative: mass outside) or the term's value; bound: the mass row's limit (kg)."""

    joint: str
    kind: str
    cost: float
    value_without: float
    bound: float = 0.0

    @property
    def constraint(self) -> str:
        """In words: 'body of <joint> realisable', '... mass >= ...' or '<joint>.<kind> >= 0'."""
        if self.kind in ("mass_min", "mass_max"):
            return f"body of {self.joint}: mass {'>=' if self.kind == 'mass_min' else '<='} {self.bound:.4g} kg"
        return WORDS[self.kind].format(j=self.joint) if self.kind in WORDS else f"{self.joint}.{self.kind} >= 0"


def constraint_costs(reg: Regressor, tau: np.ndarray, sigma: np.ndarray, cad: np.ndarray, fit: ConsistentFit,
                     body_names: list[str], noise_unit: float, bounds: LinearBounds | None = None
                     ) -> list[ConstraintCost]:
    """Cost of each binding constraint, largest first. noise_unit: weighted data cost per noise unit
    (the unconstrained fit's residual variance x the filtered noise's inflation); bounds: the plausibility
    rows the fit had."""
    extra_names = reg.names[reg.n_inertial:]
    scale = max(1.0, float(np.max(np.abs(fit.extra)))) if len(fit.extra) else 1.0
    terms = [n for n, v in zip(extra_names, fit.extra)
             if n.rsplit(".", 1)[-1] in NONNEGATIVE_TERMS and v <= ACTIVE * scale]
    out = []
    refit = dict(bounds=bounds)

    def cost(relaxed: ConsistentFit) -> float:
        return (fit.objective - relaxed.objective) / noise_unit

    for b, name in enumerate(body_names):
        eig = np.linalg.eigvalsh(pseudo_inertia(fit.inertial[10 * b:10 * b + 10]))
        if eig[0] > ACTIVE * max(eig[-1], 1e-12):
            continue
        relaxed = fit_consistent(reg, tau, sigma, cad, fit.prior_weight, free_bodies=(b,), **refit)
        eig = np.linalg.eigvalsh(pseudo_inertia(relaxed.inertial[10 * b:10 * b + 10]))[0]
        out.append(ConstraintCost(name, "body", cost(relaxed), float(eig)))
    for name in terms:
        relaxed = fit_consistent(reg, tau, sigma, cad, fit.prior_weight, free_terms=(name,), **refit)
        joint, kind = name.rsplit(".", 1)
        out.append(ConstraintCost(joint, kind, cost(relaxed), float(relaxed.extra[extra_names.index(name)])))
    if bounds is not None and len(bounds):
        slack = bounds.slack(fit.inertial)
        size = np.maximum(np.abs(bounds.G) @ np.abs(fit.inertial), 1e-12)
        for i in np.flatnonzero(slack <= ACTIVE_ROWS * size):
            relaxed = fit_consistent(reg, tau, sigma, cad, fit.prior_weight, bounds=bounds, free_rows=(int(i),))
            joint, kind = bounds.labels[i]
            without = float(bounds.slack(relaxed.inertial)[i])
            value = float(relaxed.inertial[10 * body_names.index(joint)]) if kind.startswith("mass") else without
            out.append(ConstraintCost(joint, kind, cost(relaxed), value if without < 0 else float("inf"),
                                      abs(float(bounds.h[i]))))
    # binding: the fit without it breaks it (an inactive one would only move by the solver's tolerance)
    return sorted((c for c in out if c.value_without < 0.0 or (c.kind.startswith("mass") and np.isfinite(
        c.value_without))), key=lambda c: -c.cost)
