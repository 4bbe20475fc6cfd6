"""The optional numba kernel of the single-pose FK (floating_nut_fk_compiled.py) against the numpy one."""
import logging

import numpy as np
import pytest

pytest.importorskip("numba")

from robocal.errors import InputError  # noqa: E402
from robocal.systems.floating_nut import fk as floating_nut_fk  # noqa: E402
from robocal.systems.floating_nut.fk_compiled import CompiledSinglePoseFK  # noqa: E402
from robocal.systems.floating_nut.geometry import reference_fixture, rotation_matrices  # noqa: E402
from robocal.systems.floating_nut.results import FKNotConverged
from robocal.systems.floating_nut.kinematics import (FloatingNutKinematics,  # noqa: E402
                                                        SingularHookeError)

DEG = np.pi / 180
P5 = np.array([0.05, -0.05, 0.85, 5 * DEG, -5 * DEG, 8 * DEG])    # spec §5 table pose
XYZ = reference_fixture().with_changes(euler="XYZ-moving", p0=[0.01, -0.02, 0.8, 2 * DEG, -3 * DEG, 5 * DEG])


def poses(geometry, n, seed):
    """Uniform in p0 +- 0.1 m / +-10 deg (as benchmarks/floating_nut_kinematics.py)."""
    rng = np.random.default_rng(seed)
    return geometry.p0 + np.hstack([rng.uniform(-0.1, 0.1, (n, 3)), rng.uniform(-10, 10, (n, 3)) * DEG])


def pair(geometry):
    """(numpy, numba) kinematics of one geometry."""
    return FloatingNutKinematics(geometry, use_numba=False), FloatingNutKinematics(geometry, use_numba=True)


@pytest.fixture
def fallbacks(monkeypatch):
    """Counts the numpy reruns of the compiled solver (each failure or condition warning takes one)."""
    calls = []
    solve = floating_nut_fk.SinglePoseFK.solve

    def spy(self, *args):
        if isinstance(self, CompiledSinglePoseFK):
            calls.append(args)
        return solve(self, *args)
    monkeypatch.setattr(floating_nut_fk.SinglePoseFK, "solve", spy)
    return calls


def same_solutions(kn, kc, lengths, starts, options):
    """Both paths: same pose (1e-12), iterations and residual history (round-off), or the same error."""
    for L, p_init in zip(lengths, starts):
        try:
            a = kn.fk(L, p_init=p_init, **options)
        except Exception as exc:     # noqa: BLE001  (the compiled path must raise the same)
            with pytest.raises(type(exc)) as info:
                kc.fk(L, p_init=p_init, **options)
            assert str(info.value) == str(exc)
            continue
        b = kc.fk(L, p_init=p_init, **options)
        assert b.iterations == a.iterations and len(b.history) == len(a.history)
        assert np.abs(b.pose - a.pose).max() < 1e-12
        np.testing.assert_allclose(b.history, a.history, rtol=1e-6, atol=5e-15)
        assert b.residual == b.history[-1] and type(b.iterations) is int and type(b.residual) is float


@pytest.mark.parametrize("geometry, n", [(reference_fixture(), 200), (XYZ, 50)], ids=["fixture", "XYZ-moving"])
@pytest.mark.parametrize("options", [dict(), dict(jacobian="uncompensated"), dict(compensate=False)],
                         ids=["full", "quasi", "uncompensated"])
def test_compiled_fk_follows_the_numpy_iterates(geometry, n, options, fallbacks):
    kn, kc = pair(geometry)
    assert type(kc._single_pose_solver()) is CompiledSinglePoseFK
    assert type(kn._single_pose_solver()) is floating_nut_fk.SinglePoseFK
    P = poses(geometry, n, seed=31)
    lengths = kn.ik(P, compensate=options.get("compensate", True))
    for starts in ([None] * n, P + 1e-4):                     # cold and warm
        same_solutions(kn, kc, lengths, starts, options)
        for L, p, start in zip(lengths, P, starts):
            assert np.abs(kc.fk(L, p_init=start, **options).pose - p).max() < 1e-12
    assert not fallbacks                                        # all solved in the kernel
    assert kc.fk(kc.home_lengths, **options).iterations == 0


def test_compiled_fk_wraps_the_nut_rotation_as_numpy(fallbacks):
    # home dihedrals moved by 3 rad: theta(p) near +-3 rad, so the wrap to (-pi, pi] is taken
    kn, kc = pair(reference_fixture())
    for kin in (kn, kc):
        kin._phi0 = kin._phi0 + np.where(np.arange(6) % 2, 3.0, -3.0)
    P = poses(kn.geometry, 100, seed=32)
    lengths = kn.ik(P)
    raw = kn.dihedral(P) - kn._phi0
    assert np.any((raw > np.pi) | (raw <= -np.pi))                    # some solutions need the wrap
    same_solutions(kn, kc, lengths, P + 1e-4, {})
    same_solutions(kn, kc, lengths, [None] * 100, {})
    assert not fallbacks


def test_compiled_fk_errors_are_the_numpy_errors(fallbacks):
    kn, kc = pair(reference_fixture())
    lengths = kn.ik(P5)
    for max_iter in (0, 2):
        with pytest.raises(FKNotConverged, match=f"sample 0 did not converge in {max_iter} iterations") as info:
            kc.fk(lengths, max_iter=max_iter)
        with pytest.raises(FKNotConverged) as expected:
            kn.fk(lengths, max_iter=max_iter)
        assert str(info.value) == str(expected.value) and info.value.sample == 0
    assert len(fallbacks) == 2                                        # the kernel failed, numpy reported
    same_solutions(kn, kc, [np.full(6, 0.01)], [None], dict(max_iter=20))   # unreachable lengths
    for bad in ([np.nan] + [0.9] * 5, [0.9] * 5):                     # batch path: InputError
        with pytest.raises(InputError) as info:
            kc.fk(bad)
        with pytest.raises(InputError) as expected:
            kn.fk(bad)
        assert str(info.value) == str(expected.value)


def test_compiled_fk_singular_hooke_joint(fallbacks):
    # leg 3's base axis along its strut at P5: the uncompensated solution is a gimbal lock
    g = reference_fixture()
    R = rotation_matrices(P5[3:], g.euler)
    u = P5[:3] + R @ g.m[2] - g.b[2]
    axes = g.base_axes.copy()
    axes[2] = u / np.linalg.norm(u)
    kn, kc = pair(g.with_changes(base_axes=axes))
    lengths = kn.effective_lengths(P5)
    with pytest.raises(SingularHookeError, match="leg 3") as info:
        kc.fk(lengths, compensate=False)
    with pytest.raises(SingularHookeError) as expected:
        kn.fk(lengths, compensate=False)
    assert str(info.value) == str(expected.value) and (info.value.sample, info.value.leg) == (0, 2)
    assert len(fallbacks) == 1


def test_compiled_fk_condition_warning(caplog, fallbacks):
    kn, kc = pair(reference_fixture())
    lengths = kn.ik(np.array([0, 0, 0.8, 10 * DEG, 0, 0]))           # P4, cond(J_c) ~ 5
    with caplog.at_level(logging.WARNING):
        kc.fk(lengths)
        assert not caplog.records and not fallbacks
        kc.fk(lengths, warn_condition=1.0)
        compiled = [r.getMessage() for r in caplog.records]
        caplog.clear()
        kn.fk(lengths, warn_condition=1.0)
        assert compiled == [r.getMessage() for r in caplog.records] and "condition number" in compiled[0]


def test_switches_force_numpy(monkeypatch):
    g = reference_fixture()
    monkeypatch.delenv("ROBOCAL_NO_NUMBA", raising=False)
    assert type(FloatingNutKinematics(g)._single_pose_solver()) is CompiledSinglePoseFK
    assert type(FloatingNutKinematics(g, use_numba=False)._single_pose_solver()) is floating_nut_fk.SinglePoseFK
    monkeypatch.setenv("ROBOCAL_NO_NUMBA", "1")
    kin = FloatingNutKinematics(g)
    assert type(kin._single_pose_solver()) is floating_nut_fk.SinglePoseFK
    assert np.abs(kin.fk(kin.ik(P5)).pose - P5).max() < 1e-12
    assert type(FloatingNutKinematics(g, use_numba=True)._single_pose_solver()) is CompiledSinglePoseFK
