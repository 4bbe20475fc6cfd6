"""The Levenberg-Marquardt step and stop (issue 37): the step from the triangle equals the least-squares
solution of the damped system, the R factor is a QR's whichever LAPACK routine makes it, and the solver stops
once the Gauss-Newton step predicts less than ftol x cost, at its last evaluation and within the distance that
rule allows from the exact minimum."""
import numpy as np
import pytest
from scipy.optimize import least_squares

from robocal.estimation.solve import UNBLOCKED_QR, levenberg_marquardt, lm_step, r_factor


def _triangle(rng, n, condition=1e3):
    A = rng.normal(size=(4 * n, n)) * np.logspace(0, np.log10(condition), n)
    return np.linalg.qr(A, mode="r"), rng.normal(size=n)


@pytest.mark.parametrize("damping", [0.0, 1e-6, 1e-3, 10.0])
def test_step_is_the_least_squares_solution_of_the_damped_system(damping):
    rng = np.random.default_rng(1)
    R, qtr = _triangle(rng, 31)
    D = np.linalg.norm(R, axis=0)
    A = np.vstack([R, np.sqrt(damping) * np.diag(D)])
    expected = np.linalg.lstsq(A, -np.concatenate([qtr, np.zeros(31)]), rcond=None)[0]
    # both solve the same full-rank system by orthogonal factorisations: a few ulps times its condition (1e3)
    np.testing.assert_allclose(lm_step(R, qtr, D, damping), expected, rtol=1e-11, atol=1e-11 * np.abs(expected).max())


def test_undamped_step_of_a_singular_triangle_is_the_minimum_norm_solution():
    rng = np.random.default_rng(2)
    R, qtr = _triangle(rng, 8)
    R[:, 3] = R[:, 1] * 2.0          # a column that repeats another: no unique solution
    R = np.linalg.qr(R, mode="r")
    step = lm_step(R, qtr, np.ones(8), 0.0)
    assert np.all(np.isfinite(step))
    np.testing.assert_allclose(step, np.linalg.lstsq(R, -qtr, rcond=None)[0], rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("k", [1, 13, 55, UNBLOCKED_QR, UNBLOCKED_QR + 1, 120])
def test_r_factor_is_a_qr_triangle_on_either_side_of_the_switch(k):
    rng = np.random.default_rng(k)
    A = rng.normal(size=(3 * k + 5, k))
    R = r_factor(A)
    assert R.shape == (k, k) and not np.any(np.tril(R, -1))
    # R^T R = A^T A to rounding: eps times the entries' size and the rows summed
    np.testing.assert_allclose(R.T @ R, A.T @ A, atol=1e-12 * np.abs(A.T @ A).max())
    assert np.allclose(np.abs(np.diag(R)), np.abs(np.diag(np.linalg.qr(A, mode="r"))), rtol=1e-10)


def _exponential_fit(rng):
    """y = a exp(-b t) + c with noise: a residual large enough that Gauss-Newton converges linearly."""
    t = np.linspace(0, 4, 60)
    y = 2.0 * np.exp(-1.3 * t) + 0.5 + rng.normal(0, 0.05, t.size)

    def residuals(x):
        return x[0] * np.exp(-x[1] * t) + x[2] - y

    def jacobian(x):
        e = np.exp(-x[1] * t)
        return np.column_stack([e, -x[0] * t * e, np.ones_like(t)])
    return residuals, jacobian


def test_stops_at_its_last_evaluation_within_what_ftol_allows():
    residuals, jacobian = _exponential_fit(np.random.default_rng(3))
    calls = []

    def fun(x):
        calls.append(np.array(x))
        return residuals(x), jacobian(x), np.arange(60)

    ftol = 1e-12
    sol = levenberg_marquardt(fun, np.array([1.0, 0.5, 0.0]), ftol=ftol, xtol=1e-15, gtol=1e-15)
    assert sol.success and sol.message == "cost reduction below ftol"
    assert np.array_equal(calls[-1], sol.x)          # no trial step evaluated after the last accepted one
    # every accepted step gained more than ftol: none was spent on a reduction at the cost's rounding level
    h = sol.history
    assert all(a.cost - b.cost > ftol * a.cost for a, b in zip(h, h[1:]))
    exact = least_squares(residuals, sol.x, jac=jacobian, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    # the rule: the Gauss-Newton step left, |J dx|, is below sqrt(2 ftol cost) (first order in dx)
    gap = np.linalg.norm(jacobian(exact) @ (sol.x - exact))
    assert gap <= 1.5 * np.sqrt(2 * ftol * sol.cost)


def test_covariance_of_an_r_factor_is_that_of_its_rows():
    from robocal.estimation.identifiability import covariance
    rng = np.random.default_rng(4)
    A = rng.normal(size=(200, 12)) * np.logspace(0, 3, 12)
    R = r_factor(A)
    expected = np.linalg.inv(A.T @ A)        # condition 1e3 squared: 1e-10 relative is ample
    np.testing.assert_allclose(covariance(R, 2.0), 2.0 * expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    np.testing.assert_allclose(covariance(A, 2.0), covariance(R, 2.0), rtol=1e-10, atol=1e-12 * np.abs(expected).max())
