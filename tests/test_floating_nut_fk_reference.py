"""Every FK path of the floating-nut hexapod (numpy single pose, numpy batch, numba kernel when installed)
gives the pose of a plain reference (tests/reference_floating_nut_fk.py) to 1e-10.

Tolerance: Newton on l_c(p) = L stops at |residual| < 1e-12 m, then a chord step takes the pose error to
about cond(J_c) * 1e-16 m (cond ~5 here); the reference's finite-difference Jacobian only changes its
convergence rate, not its root. 1e-10 (m and rad) is the agreement the paths must keep, far above round-off.
"""
import importlib.util

import numpy as np
import pytest

from robocal.systems.floating_nut.geometry import reference_fixture
from robocal.systems.floating_nut.kinematics import FloatingNutKinematics
from reference_floating_nut_fk import command_lengths, forward

DEG = np.pi / 180
GEOMETRIES = {"ZYX": reference_fixture(),
              "XYZ": reference_fixture().with_changes(euler="XYZ-moving",
                                                      p0=[0.01, -0.02, 0.8, 2 * DEG, -3 * DEG, 5 * DEG])}
SOLVERS = [False, True] if importlib.util.find_spec("numba") else [False]


def box_poses(geometry, n, seed):
    rng = np.random.default_rng(seed)
    return geometry.p0 + np.hstack([rng.uniform(-0.1, 0.1, (n, 3)), rng.uniform(-10, 10, (n, 3)) * DEG])


@pytest.mark.parametrize("name", GEOMETRIES)
@pytest.mark.parametrize("compensate", [True, False])
def test_all_fk_paths_give_the_reference_pose(name, compensate):
    g = GEOMETRIES[name]
    P = box_poses(g, 6, seed=3)
    L = np.array([command_lengths(g, p, compensate) for p in P])
    want = np.array([forward(g, l, compensate) for l in L])
    assert np.abs(want - P).max() < 1e-10                       # the reference inverts its own IK
    for use_numba in SOLVERS:
        kin = FloatingNutKinematics(g, use_numba=use_numba)
        np.testing.assert_allclose(kin.ik(P, compensate=compensate), L, rtol=0, atol=1e-12)
        for jacobian in ("full", "uncompensated"):
            single = np.array([kin.fk(l, compensate=compensate, jacobian=jacobian).pose for l in L])
            np.testing.assert_allclose(single, want, rtol=0, atol=1e-10)
        batch = kin.fk(L, compensate=compensate).pose
        np.testing.assert_allclose(batch, want, rtol=0, atol=1e-10)
        warm = np.array([kin.fk(l, p_init=p + 1e-3, compensate=compensate).pose for l, p in zip(L, P)])
        np.testing.assert_allclose(warm, want, rtol=0, atol=1e-10)
