"""Physical consistency: the pseudo-inertia PSD test is necessary and sufficient, and the
PSD-constrained least squares (psd_qp.py) returns realisable bodies at the constrained optimum."""
from pathlib import Path

import numpy as np
import pytest

from robocal.dynamics.reduced_model import reduced_model
from robocal.dynamics.inertial import is_physically_consistent, parameter_vector, pseudo_inertia
from robocal.dynamics.psd_qp import TO_SVEC, nearest_realisable, solve_psd_qp

URDF = Path(__file__).resolve().parents[1] / "examples/tiago_mocap/data/tiago_48_schunk.urdf"
TIAGO_JOINTS = ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)]


def point_masses(masses, points) -> np.ndarray:
    """10 parameters about the origin of point masses (a realisable, possibly degenerate body)."""
    p = np.zeros(10)
    for m, r in zip(masses, points):
        r = np.asarray(r, float)
        inertia = m * (np.dot(r, r) * np.eye(3) - np.outer(r, r))
        p += np.r_[m, m * r, inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2], inertia[1, 2], inertia[2, 2]]
    return p


def test_mass_distributions_pass_and_only_they():
    rng = np.random.default_rng(3)
    for _ in range(50):
        n = rng.integers(1, 6)
        body = point_masses(rng.uniform(0.1, 2.0, n), rng.normal(0, 0.3, (n, 3)))
        assert is_physically_consistent(body)          # sufficient direction: every distribution passes
    # a single point mass and a thin rod are degenerate (pseudo-inertia rank 1, 2): still realisable
    assert is_physically_consistent(point_masses([1.0], [[0.2, 0.0, 0.1]]))
    assert is_physically_consistent(point_masses([1.0, 1.0], [[0.1, 0, 0], [-0.1, 0, 0]]))
    # positive mass and positive-definite rotational inertia, but the triangle inequality is broken
    # (Ixx + Iyy < Izz): no mass distribution has it, and the test says so
    broken = np.r_[1.0, 0, 0, 0, 0.01, 0, 0.01, 0, 0, 0.03]
    assert np.all(np.linalg.eigvalsh([[0.01, 0, 0], [0, 0.01, 0], [0, 0, 0.03]]) > 0)
    assert not is_physically_consistent(broken)
    # first moment too large for the second moments (centre of mass outside the body's extent)
    assert not is_physically_consistent(np.r_[1.0, 0.5, 0, 0, 0.01, 0, 0.01, 0, 0, 0.01])
    assert not is_physically_consistent(np.r_[-1.0, 0, 0, 0, 0.01, 0, 0.01, 0, 0, 0.01])


def test_tiago_cad_arm_1_is_not_realisable():
    """The URDF's arm_1 link breaks the triangle inequality (found by this test, reported in
    docs/dynamics_tiago.md); the other seven bodies are realisable."""
    model = reduced_model(URDF, TIAGO_JOINTS)
    bodies = parameter_vector(model).reshape(-1, 10)
    verdict = {model.names[j + 1]: is_physically_consistent(p) for j, p in enumerate(bodies)}
    assert [k for k, ok in verdict.items() if not ok] == ["arm_1_joint"]


def test_svec_map_is_invertible_and_isometric():
    """Clarabel's PSD triangle cone is defined in isometric coordinates: norms must be kept, and
    the map from the 10 inertial parameters must be one to one."""
    rng = np.random.default_rng(0)
    p = rng.normal(size=10)
    assert np.allclose(np.linalg.solve(TO_SVEC, TO_SVEC @ p), p, atol=1e-12)
    J = pseudo_inertia(p)
    assert np.isclose(np.linalg.norm(TO_SVEC @ p), np.linalg.norm(J), rtol=1e-12)


def test_nearest_realisable_keeps_realisable_bodies_and_repairs_others():
    rng = np.random.default_rng(3)
    body = point_masses(rng.uniform(0.5, 1.5, 4), rng.normal(0, 0.2, (4, 3)))
    assert np.allclose(nearest_realisable(body), body, atol=1e-12)
    broken = body.copy()
    broken[4:10] = [0.01, 0, 0.01, 0, 0, 0.05]          # triangle inequality broken
    assert not is_physically_consistent(broken)
    assert is_physically_consistent(nearest_realisable(broken))


def objective(H, q, x):
    return 0.5 * x @ H @ x - q @ x


@pytest.mark.parametrize("feasible_optimum", [True, False])
def test_psd_qp_reaches_the_constrained_optimum(feasible_optimum):
    """Synthetic truth: with a feasible unconstrained optimum the solver returns it; otherwise its
    answer is realisable and no realisable point nearby (random feasible perturbations) is better."""
    rng = np.random.default_rng(7)
    bodies = [point_masses(rng.uniform(0.5, 1.5, 4), rng.normal(0, 0.2, (4, 3))) for _ in range(2)]
    truth = np.r_[np.concatenate(bodies), 0.3, 1.2]
    if not feasible_optimum:
        truth[4:10] = [0.01, 0, 0.01, 0, 0, 0.05]     # first body: triangle inequality broken
    A = rng.normal(size=(200, 22))
    H, q = A.T @ A, A.T @ (A @ truth)
    lower = np.array([-np.inf, 0.0])
    res = solve_psd_qp(H, q, 2, lower)
    assert res.converged
    assert all(is_physically_consistent(b) for b in res.x[:20].reshape(2, 10))
    if feasible_optimum:
        assert np.allclose(res.x, truth, atol=1e-5)
    else:
        assert not is_physically_consistent(truth[:10])
        # convex problem: the optimum is no worse than any point on a segment towards a feasible point
        best = objective(H, q, res.x)
        for _ in range(50):
            feasible = np.r_[np.concatenate([point_masses(rng.uniform(0.1, 2, 3), rng.normal(0, 0.3, (3, 3)))
                                             for _ in range(2)]), rng.normal(), rng.uniform(0, 2)]
            for t in (1e-3, 1e-2, 1e-1):
                assert objective(H, q, (1 - t) * res.x + t * feasible) >= best - 1e-7 * abs(best)
