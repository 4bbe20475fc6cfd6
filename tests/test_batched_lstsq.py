"""The chunked least-squares path against the dense one: same triangle, same solution."""
import numpy as np
import pytest

from synthetic_cases import ur5_pose_problem
from robocal.design.simulate import perturb, simulate_measurements
from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.chunked_lstsq import ChunkedJacobian, evaluate_chunked
from robocal.estimation.solve import levenberg_marquardt, triangle


def _problem(seed=4, n=60):
    rng = np.random.default_rng(seed)
    problem = ur5_pose_problem(rng, n)
    # keep the identifiable subset so the solution is unique (base + joints + tool are confounded)
    problem.params.fix("base.*", "shoulder_pan_joint.*", "tool0.*")
    simulate_measurements(problem, perturb(problem.params, rng), rng)
    problem.residuals[0].measurements[:3, :3] += 0.01     # three outliers for the robust loss
    return problem


def test_chunked_triangle_has_the_dense_gram_matrix():
    problem = _problem()
    ev = problem.evaluate()
    ch = evaluate_chunked(problem, chunk_terms=7)
    np.testing.assert_array_equal(ch.group, ev.group)
    assert np.abs(ch.r - ev.r).max() <= 1e-14 * np.abs(ev.r).max()
    n = ev.J.shape[1]
    w = np.random.default_rng(0).uniform(0.5, 1.0, len(ev.r))
    for weights in (np.ones(len(ev.r)), w):
        A = np.column_stack([ev.J, ev.r]) * weights[:, None]
        T = ch.J.triangle(weights)
        # Gram matrices agree to rounding: eps * |A|^2 * (a few) at most
        assert np.abs(T.T @ T - A.T @ A).max() <= 1e-12 * np.abs(A.T @ A).max()
        assert np.abs(triangle(ev.J, ev.r, weights, n).T @ triangle(ev.J, ev.r, weights, n) - A.T @ A).max() \
            <= 1e-12 * np.abs(A.T @ A).max()


@pytest.mark.parametrize("loss", ["linear", "huber"])
def test_chunked_fit_reaches_the_dense_solution(loss):
    problem = _problem()
    x0 = problem.params.free_values()

    def dense(x):
        problem.params.set_free_values(x)
        ev = problem.evaluate()
        return ev.r, ev.J, ev.group

    def chunked(x):
        problem.params.set_free_values(x)
        ev = evaluate_chunked(problem, chunk_terms=11)
        return ev.r, ev.J, ev.group

    a = levenberg_marquardt(dense, x0, loss=loss)
    b = levenberg_marquardt(chunked, x0, loss=loss)
    assert a.success and b.success
    # both stop at the same least-squares minimum, each where a further step gains less than ftol x cost
    # (default ftol 1e-12); the cost grows as 1/2 |R dx|^2 away from it, so the two stopping points differ by
    # at most sqrt(2 ftol cost) in the metric of R (1 = a one-sigma move of the fit): ~6e-4 sigma here
    n = len(a.x)
    assert np.linalg.norm(a.triangle[:n, :n] @ (a.x - b.x)) <= np.sqrt(2e-12 * a.cost)
    assert np.abs(a.triangle.T @ a.triangle - b.triangle.T @ b.triangle).max() <= 1e-10 * np.abs(
        a.triangle.T @ a.triangle).max()


def test_calibrate_in_chunks_gives_the_whole_result():
    """calibrate() with chunk_terms (registration, default prior, selection, solve, covariance and classes all
    from triangles) against the whole-Jacobian calibrate() on the same data."""
    rng = np.random.default_rng(7)
    whole, chunked = (ur5_pose_problem(np.random.default_rng(7), 60) for _ in range(2))
    truth = perturb(whole.params, rng)
    simulate_measurements(whole, truth, rng)
    chunked.residuals[0].set_measurements(whole.residuals[0].measurements.copy())
    a = calibrate(whole)
    b = calibrate(chunked, CalibrationOptions(chunk_terms=7))
    assert isinstance(b.solve.jac, ChunkedJacobian) and not isinstance(a.solve.jac, ChunkedJacobian)
    assert a.selection.independent == b.selection.independent
    assert a.default_prior.applied == b.default_prior.applied and a.determinacy.classes == b.determinacy.classes
    names = whole.params.free_names
    assert names == chunked.params.free_names
    xa, xb = whole.params.free_values(), chunked.params.free_values()
    n = len(xa)
    # as above: two stopping points of the same minimum differ by at most sqrt(2 ftol cost) in R's metric
    assert np.linalg.norm(a.solve.triangle[:n, :n] @ (xa - xb)) <= np.sqrt(2e-12 * a.solve.cost) + 1e-12
    # standard errors from the same Gram matrix up to that move: 1e-6 relative is far above rounding
    se_a = np.array([whole.params[k].stderr for k in names])
    se_b = np.array([chunked.params[k].stderr for k in names])
    assert np.all(np.abs(se_a - se_b) <= 1e-6 * se_a)
    assert abs(a.sigma2 - b.sigma2) <= 1e-9 * a.sigma2
    for sa, sb in zip(a.before + a.after, b.before + b.after):
        assert sa.norm_rms.keys() == sb.norm_rms.keys()
        assert all(abs(sa.norm_rms[u] - sb.norm_rms[u]) <= 1e-9 * sa.norm_rms[u] for u in sa.norm_rms)
