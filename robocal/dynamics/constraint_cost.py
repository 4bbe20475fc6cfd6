"""Which physical constraints hold the consistent fit away from the unconstrained one.

When the consistent model predicts worse than OLS, the question is which constraint the data push
against: a body that cannot be a mass distribution with the inertia the data ask for, or a friction
or rotor-inertia term the data want negative. Each constraint (a body's pseudo-inertia PSD, a term's
bound) is dropped in turn, the fit repeated at the same prior weight, and the fall of its objective
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
from robocal.dynamics.regression import Regressor

#: noise units below which a cost is within the solver's tolerance (see above)
MEASURABLE_COST = 0.5


@dataclass
class ConstraintCost:
    """joint: the body's joint or the term's; kind: 'body' (its pseudo-inertia PSD) or the term's kind
    (coulomb, viscous, armature: >= 0); cost: fall of the fit's objective when it is dropped, in noise
    units; value_without: the body's smallest pseudo-inertia eigenvalue (kg m^2) or the term's value, in
    the fit without it."""

    joint: str
    kind: str
    cost: float
    value_without: float

    @property
    def constraint(self) -> str:
        """In words: 'body of <joint> realisable' or '<joint>.<kind> >= 0'."""
        return f"body of {self.joint} realisable" if self.kind == "body" else f"{self.joint}.{self.kind} >= 0"


def constraint_costs(reg: Regressor, tau: np.ndarray, sigma: np.ndarray, cad: np.ndarray, fit: ConsistentFit,
                     body_names: list[str], noise_unit: float) -> list[ConstraintCost]:
    """Cost of each binding constraint, largest first. noise_unit: weighted data cost per noise unit
    (the unconstrained fit's residual variance x the filtered noise's inflation)."""
    extra_names = reg.names[reg.n_inertial:]
    terms = [n for n in extra_names if n.rsplit(".", 1)[-1] in NONNEGATIVE_TERMS]
    out = []

    def cost(relaxed: ConsistentFit) -> float:
        return (fit.objective - relaxed.objective) / noise_unit

    for b, name in enumerate(body_names):
        relaxed = fit_consistent(reg, tau, sigma, cad, fit.prior_weight, free_bodies=(b,))
        eig = np.linalg.eigvalsh(pseudo_inertia(relaxed.inertial[10 * b:10 * b + 10]))[0]
        out.append(ConstraintCost(name, "body", cost(relaxed), float(eig)))
    for name in terms:
        relaxed = fit_consistent(reg, tau, sigma, cad, fit.prior_weight, free_terms=(name,))
        joint, kind = name.rsplit(".", 1)
        out.append(ConstraintCost(joint, kind, cost(relaxed), float(relaxed.extra[extra_names.index(name)])))
    # binding: the fit without it breaks it (an inactive one would only move by the solver's tolerance)
    return sorted((c for c in out if c.value_without < 0.0), key=lambda c: -c.cost)
