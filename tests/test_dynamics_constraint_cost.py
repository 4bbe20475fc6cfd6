"""constraint_cost.py names the physical constraints that hold the consistent fit away from the
unconstrained one, with what each costs: synthetic truths whose unconstrained optimum breaks one
known constraint."""
import numpy as np

from robocal.dynamics.constraint_cost import constraint_costs
from robocal.dynamics.consistent_fit import fit_consistent
from robocal.dynamics.inertial import is_physically_consistent
from robocal.dynamics.psd_qp import solve_psd_qp
from robocal.dynamics.regression import Regressor
from test_dynamics_tiago_consistency import point_masses

NOISE = 0.01
NAMES = [f"b{b}.p{k}" for b in range(2) for k in range(10)] + ["j.offset", "j.armature", "j.viscous"]


def synthetic(truth, seed=0, rows=400):
    """A well-conditioned random regressor (one recorded joint), torques with white noise NOISE."""
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(rows, len(truth)))
    tau = (X @ truth + rng.normal(0, NOISE, rows)).reshape(-1, 1)
    return Regressor(X, NAMES, 20, [0]), tau


def bodies(rng):
    return np.concatenate([point_masses(rng.uniform(0.5, 1.5, 4), rng.normal(0, 0.3, (4, 3))) for _ in range(2)])


def costs_of(truth, seed=0):
    reg, tau = synthetic(truth, seed)
    sigma = np.array([NOISE])
    fit = fit_consistent(reg, tau, sigma, truth[:20], 1e-8)       # prior negligible: the data decide
    return reg, tau, constraint_costs(reg, tau, sigma, truth[:20], fit, ["b0", "b1"], noise_unit=1.0)


def test_a_negative_rotor_inertia_is_named_with_its_cost_and_value():
    rng = np.random.default_rng(1)
    truth = np.r_[bodies(rng), 0.2, -0.5, 0.3]          # the data ask for a negative rotor inertia
    reg, tau, costs = costs_of(truth)
    assert costs[0].constraint == "j.armature >= 0"
    assert [c.constraint for c in costs] == ["j.armature >= 0"]     # the bodies and viscous term are not binding
    # without it the fit is the plain least squares one (every other constraint inactive): its value
    # and the data cost it saves agree with lstsq
    w = 1.0 / NOISE
    x, *_ = np.linalg.lstsq(reg.X * w, tau[:, 0] * w, rcond=None)
    assert abs(costs[0].value_without - x[21]) < 1e-5
    se = NOISE / np.sqrt(len(tau))                       # the column has unit variance
    assert abs(costs[0].value_without + 0.5) < 4 * se
    constrained = fit_consistent(reg, tau, np.array([NOISE]), truth[:20], 1e-8)
    lstsq_cost = float(np.sum((reg.X @ x * w - tau[:, 0] * w) ** 2))
    assert abs(costs[0].cost - (constrained.data_cost - lstsq_cost)) < 1e-4 * constrained.data_cost
    assert costs[0].cost > 1000                          # 0.5 is ~1000 standard errors from the bound


def test_a_body_the_data_make_unrealisable_is_named():
    rng = np.random.default_rng(2)
    truth = np.r_[bodies(rng), 0.2, 0.4, 0.3]
    truth[4:10] = [0.01, 0, 0.01, 0, 0, 0.05]           # body b0: triangle inequality broken
    assert not is_physically_consistent(truth[:10])
    _, _, costs = costs_of(truth)
    assert [c.constraint for c in costs] == ["body of b0 realisable"]
    assert costs[0].value_without < 0 and costs[0].cost > 0


def test_nothing_binds_when_the_truth_is_physical():
    rng = np.random.default_rng(3)
    truth = np.r_[bodies(rng), 0.2, 0.4, 0.3]
    assert costs_of(truth)[2] == []


def test_a_free_body_keeps_the_unconstrained_optimum():
    """solve_psd_qp(free_bodies=(0,)): body 0 unconstrained, so an infeasible body 0 is returned as is."""
    rng = np.random.default_rng(4)
    truth = np.r_[bodies(rng), 0.4, 0.3]
    truth[4:10] = [0.01, 0, 0.01, 0, 0, 0.05]
    A = rng.normal(size=(200, 22))
    H, q = A.T @ A, A.T @ (A @ truth)
    lower = np.array([-np.inf, 0.0])
    assert np.allclose(solve_psd_qp(H, q, 2, lower, free_bodies=(0,)).x, truth, atol=1e-9)
    assert is_physically_consistent(solve_psd_qp(H, q, 2, lower).x[:10])
