"""The chunked least-squares path against the dense one: same triangle, same solution."""
import numpy as np
import pytest

from synthetic_cases import ur5_pose_problem
from robocal.design.simulate import perturb, simulate_measurements
from robocal.estimation.chunked_lstsq import evaluate_chunked
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
    # both stop at the same least-squares minimum; 1e-10 of the largest parameter is far below its
    # standard error (~1e-5 of it at 60 poses with 50 um / 50 urad noise)
    assert np.abs(a.x - b.x).max() <= 1e-10 * np.abs(a.x).max()
    assert np.abs(a.triangle.T @ a.triangle - b.triangle.T @ b.triangle).max() <= 1e-10 * np.abs(
        a.triangle.T @ a.triangle).max()
