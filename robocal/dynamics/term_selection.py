"""Which optional model terms the training data ask for: a spring, asymmetric friction, an effort delay.

The config's model.terms are always in the model; model.candidate_terms are tried per recorded joint and
kept when the training data show them. The rule, fixed before any validation window is looked at: a
candidate is kept when adding it alone to the model lowers the weighted training residual of the
unconstrained fit by more than the chi-square (1 degree of freedom) quantile at 1 - 0.05 / (number of
candidates tried) (a Bonferroni 5 % test), in noise units (the unconstrained fit's residual variance times
the filtered noise's inflation, serial_correlation.py): a likelihood-ratio test that allows for the
correlation the low-pass leaves between decimated samples.

  spring              column q_j (with the offset: a counterbalance, constant plus linear in position)
  coulomb_asymmetric  Fc+ and Fc- on either side of zero speed (adds max(tanh, 0) to the span)
  viscous_asymmetric  Fv+ and Fv- (adds max(v, 0) to the span)
  delay               the joint's torque reading lags its motion by d: the measured torque at t + d is
                      the model's at t; d on a grid of the log's sample step within +-delay_max_s, the
                      one minimising the residual, kept by the same test with the quantile at
                      1 - 0.05 / (grid points x joints) (the search picks the best of many shifts)

Each test projects on the base regressor's orthonormal basis once (no refit per candidate), so the whole
search costs a few milliseconds.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.dynamics.chi_square import chi2_quantile

#: the column a candidate adds to the span of the model's columns
ADDED_COLUMN = {"spring": "spring", "coulomb_asymmetric": "coulomb_pos", "viscous_asymmetric": "viscous_pos"}
CANDIDATES = tuple(ADDED_COLUMN) + ("delay",)
#: a candidate column whose part outside the model's span is below this share of its norm is confounded
CONFOUNDED = 1e-6
TEST_LEVEL = 0.05


@dataclass
class TermTest:
    """joint, term; statistic: fall of the weighted training residual in noise units; threshold: the
    quantile it had to exceed; kept; value: the delay (s) for a delay test; note: why not tested."""

    joint: str
    term: str
    statistic: float
    threshold: float
    kept: bool
    value: float = 0.0
    note: str = ""


class Projector:
    """Residuals of weighted least squares on a fixed weighted base regressor Xw (rows x columns)."""

    def __init__(self, Xw: np.ndarray):
        self.Q, _ = np.linalg.qr(Xw)

    def residual(self, y: np.ndarray) -> np.ndarray:
        return y - self.Q @ (self.Q.T @ y)


def choose_delays(projector: Projector, weights: np.ndarray, torque_at, joints: list[str], grid: np.ndarray,
                  noise_unit: float) -> list[TermTest]:
    """Per recorded joint (k, name), the delay of `grid` (s) minimising the residual with the others at
    zero. torque_at(k, d): the training torques (T, nr) with joint k's reading shifted by d; weights:
    per row (1/sigma, rows sample-major)."""
    base = torque_at(None, 0.0)
    rss0 = float(np.sum(projector.residual(base.reshape(-1) * weights) ** 2))
    threshold = chi2_quantile(1 - TEST_LEVEL / (len(grid) * len(joints)), 1)
    out = []
    for k, name in enumerate(joints):
        rss = [float(np.sum(projector.residual(torque_at(k, d).reshape(-1) * weights) ** 2)) for d in grid]
        best = int(np.argmin(rss))
        stat = (rss0 - rss[best]) / noise_unit
        out.append(TermTest(name, "delay", stat, threshold, bool(stat > threshold and grid[best] != 0.0),
                            float(grid[best])))
    return out


def added_column_tests(projector: Projector, weights: np.ndarray, y: np.ndarray, candidates: list[tuple[str, str]],
                 columns: dict[tuple[str, str], np.ndarray], noise_unit: float, n_tests: int) -> list[TermTest]:
    """Each (joint, term) of `candidates` with its added column (unweighted, rows as y): the residual's
    fall when that column joins the base (one degree of freedom)."""
    r0 = projector.residual(y * weights)
    threshold = chi2_quantile(1 - TEST_LEVEL / max(n_tests, 1), 1)
    out = []
    for joint, term in candidates:
        c = columns[(joint, term)] * weights
        c_perp = projector.residual(c)
        norm = float(c_perp @ c_perp)
        if norm <= (CONFOUNDED * np.linalg.norm(c)) ** 2:
            out.append(TermTest(joint, term, 0.0, threshold, False,
                                note="confounded with the model's columns on this window"))
            continue
        stat = float(c_perp @ r0) ** 2 / norm / noise_unit
        out.append(TermTest(joint, term, stat, threshold, stat > threshold))
    return out


def delay_grid(step_s: float, max_s: float) -> np.ndarray:
    """0, +-step, ... within +-max_s."""
    n = int(np.floor(max_s / step_s + 1e-9))
    return step_s * np.arange(-n, n + 1)
