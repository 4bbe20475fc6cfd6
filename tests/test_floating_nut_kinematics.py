"""Closed-form IK with nut-rotation compensation and Newton FK (spec seed-002 §7.3, tests 1-4, 8-12)."""
import numpy as np
import pytest

from robocal.errors import AssemblyError, InputError
from robocal.systems.floating_nut.geometry import (FloatingNutGeometry, reference_fixture,
                                                      rotation_matrices, sigma_from_thread, thread_hand)
from robocal.systems.floating_nut.results import FKNotConverged
from robocal.systems.floating_nut.kinematics import (FloatingNutKinematics,
                                                        SingularHookeError)

DEG = np.pi / 180


@pytest.fixture(scope="module")
def kin():
    return FloatingNutKinematics(reference_fixture())


def random_poses(geometry, n, seed, box=(0.1, 10 * DEG)):
    """Poses uniformly in +-0.1 m / +-10 deg about p0."""
    rng = np.random.default_rng(seed)
    offsets = np.hstack([rng.uniform(-box[0], box[0], (n, 3)), rng.uniform(-box[1], box[1], (n, 3))])
    return geometry.p0 + offsets


# Spec §5 reference table: poses (m, deg), theta (deg), l_a (um), l (m).
P_TABLE = {
    "P1": ([0, 0, 0.8, 0, 0, 10], [8.503557, 7.849111] * 3, [236.2099, 218.0309] * 3,
           [0.862733, 0.922747] * 3),
    "P2": ([0.1, 0, 0.8, 0, 0, 0], [-0.174655, 0.174655, 1.757807, 1.740926, -1.740926, -1.757807],
           [-4.8515, 4.8515, 48.8280, 48.3591, -48.3591, -48.8280],
           [0.857639, 0.857639, 0.933115, 0.894790, 0.894790, 0.933115]),
    "P3": ([0, 0, 0.9, 0, 0, 0], [-0.427037, 0.427037] * 3, [-11.8621, 11.8621] * 3, [0.980968] * 6),
    "P4": ([0, 0, 0.8, 10, 0, 0], [-2.961719, -3.195136, 3.243630, -0.559935, -0.826456, 4.420604],
           [-82.2700, -88.7538, 90.1008, -15.5538, -22.9571, 122.7946],
           [0.841507, 0.937232, 0.950353, 0.901425, 0.879756, 0.833250]),
    "P5": ([0.05, -0.05, 0.85, 5, -5, 8], [7.295120, 5.597100, 9.447946, 8.855239, 4.075170, 7.002543],
           [202.6422, 155.4750, 262.4429, 245.9789, 113.1992, 194.5151],
           [0.905077, 0.975761, 0.981321, 0.960397, 0.860758, 0.955098]),
}


def table_pose(name):
    p = np.array(P_TABLE[name][0], dtype=float)
    p[3:] *= DEG
    return p


def test_home_identity(kin):
    lc, d = kin.ik(kin.geometry.p0, return_details=True)
    assert np.all(d.theta == 0.0) and np.all(d.additional == 0.0)
    np.testing.assert_array_equal(lc, d.lengths)
    np.testing.assert_allclose(lc, 0.8901116038, atol=5e-11)
    np.testing.assert_allclose(np.rad2deg(kin.home_dihedral), [-37.831113, 37.831113] * 3, atol=1e-6)


@pytest.mark.parametrize("name", sorted(P_TABLE))
def test_fixture_regression(kin, name):
    _, theta, la, length = P_TABLE[name]
    lc, d = kin.ik(table_pose(name), return_details=True)
    # tolerances: half a unit of the table's last printed digit
    np.testing.assert_allclose(np.rad2deg(d.theta), theta, atol=0.5e-6)
    np.testing.assert_allclose(d.additional * 1e6, la, atol=0.5e-4)
    np.testing.assert_allclose(d.lengths, length, atol=0.5e-6)
    np.testing.assert_allclose(lc, d.lengths + d.additional, atol=1e-15)


def test_symmetry_yaw_and_heave(kin):
    for pose in ([0, 0, 0.8, 0, 0, 7 * DEG], [0, 0, 0.87, 0, 0, 0]):
        theta = kin.nut_rotation(pose)
        np.testing.assert_allclose(theta[[2, 4]], theta[0], atol=1e-14)
        np.testing.assert_allclose(theta[[3, 5]], theta[1], atol=1e-14)
    heave = kin.nut_rotation([0, 0, 0.87, 0, 0, 0])
    assert abs(heave[0]) > 1e-3
    np.testing.assert_allclose(heave[0], -heave[1], atol=1e-14)


@pytest.mark.parametrize("mode, max_iter", [("full", 4), ("uncompensated", 6), ("fd", 6)])
def test_ik_fk_round_trip(kin, mode, max_iter):
    poses = random_poses(kin.geometry, 1000, seed=4)
    res = kin.fk(kin.ik(poses), jacobian=mode)
    assert np.abs(res.pose - poses).max() <= 1e-12
    assert res.iterations.max() <= max_iter
    assert res.residual.max() < 1e-12


def test_fk_ik_round_trip(kin):
    rng = np.random.default_rng(5)
    lengths = kin.home_lengths + rng.uniform(-0.04, 0.04, (300, 6))
    res = kin.fk(lengths)
    assert np.abs(kin.ik(res.pose) - lengths).max() <= 1e-12


def test_single_pose_shapes(kin):
    p = table_pose("P5")
    res = kin.fk(kin.ik(p))
    assert res.pose.shape == (6,) and isinstance(res.iterations, int)
    assert np.abs(res.pose - p).max() < 1e-12
    assert kin.jacobian(p).shape == (6, 6) and kin.hooke_angles(p).shape == (6, 4)


def test_warm_start(kin):
    poses = random_poses(kin.geometry, 200, seed=6)
    step = np.random.default_rng(7).uniform(-1e-4, 1e-4, poses.shape)
    res = kin.fk(kin.ik(poses + step), p_init=poses)
    assert res.iterations.max() <= 3
    assert np.abs(res.pose - poses - step).max() < 1e-12


def test_compensated_vs_uncompensated(kin):
    lc_p1 = kin.ik(table_pose("P1"))
    wrong = kin.fk(lc_p1, compensate=False).pose - table_pose("P1")
    assert wrong[2] * 1e6 == pytest.approx(253.44, abs=0.01)            # spec §5: dz = +253.44 um
    assert np.rad2deg(wrong[5]) * 1e3 == pytest.approx(-0.49, abs=0.01)  # dgamma = -0.49 mdeg

    poses = random_poses(kin.geometry, 2000, seed=8)
    lc = kin.ik(poses)
    la_max = np.abs(kin.additional_lengths(poses)).max()
    pos_err = np.linalg.norm(kin.fk(lc, compensate=False).pose[:, :3] - poses[:, :3], axis=1).max()
    # spec §5 (approximate, random sample): max |l_a| ~ 0.48 mm, max position error ~ 0.55 mm
    assert 0.3e-3 < la_max < 0.6e-3
    assert 0.3e-3 < pos_err < 1.0e-3
    exact = kin.fk(kin.ik(poses, compensate=False), compensate=False)
    assert np.abs(exact.pose - poses).max() < 1e-12


def test_lead_scaling_and_sign():
    g = reference_fixture()
    poses = random_poses(g, 50, seed=9)
    base = FloatingNutKinematics(g).additional_lengths(poses)
    two_start = FloatingNutGeometry.from_thread(g.b, g.m, g.p0, starts=2, pitch=0.005, hand="left")
    np.testing.assert_allclose(FloatingNutKinematics(two_start).additional_lengths(poses), base, atol=1e-18)
    np.testing.assert_allclose(FloatingNutKinematics(g.with_changes(lead=0.02)).additional_lengths(poses),
                               2 * base, atol=1e-18)
    flipped = g.with_changes(sigma=[1, -1, 1, -1, 1, -1])
    np.testing.assert_allclose(FloatingNutKinematics(flipped).additional_lengths(poses),
                               base * [1, -1, 1, -1, 1, -1], atol=1e-18)
    no_lead = FloatingNutKinematics(g.with_changes(lead=0.0))
    np.testing.assert_array_equal(no_lead.ik(poses), no_lead.ik(poses, compensate=False))


def test_thread_hand_convention():
    assert sigma_from_thread("right", "platform") == -1
    assert sigma_from_thread("left", "platform") == 1
    assert sigma_from_thread("right", "base") == 1
    assert thread_hand(-1) == "right" and thread_hand(1, "base") == "right"
    g = FloatingNutGeometry.from_thread(reference_fixture().b, reference_fixture().m, [0, 0, 0.8, 0, 0, 0],
                                        starts=3, pitch=0.004, hand="right")
    assert np.all(g.sigma == -1) and np.allclose(g.lead, 0.012) and g.thread_hands == ["right"] * 6
    np.testing.assert_allclose(g.pitch, 0.004)


def test_patent_unsigned_mode(kin):
    poses = random_poses(kin.geometry, 300, seed=10)
    phi0 = kin.home_dihedral
    phi = kin.dihedral(poses)
    theta = kin.nut_rotation(poses)
    eq2 = kin.nut_rotation(poses, patent_unsigned=True)
    same_sign = np.sign(phi) == np.sign(phi0)
    assert same_sign.mean() > 0.9
    np.testing.assert_allclose(np.abs(eq2[same_sign]), np.abs(theta[same_sign]), atol=1e-9)
    # legs whose home dihedral is negative: eq. (2) without a direction rule has the wrong sign
    wrong = same_sign & (phi0 < 0) & (np.abs(theta) > 1e-6)
    assert wrong.sum() > 100
    assert np.all(np.sign(eq2[wrong]) == -np.sign(theta[wrong]))


def strut_axis(geometry, pose, leg):
    """Unit strut axis s_i at a pose, computed here from the definition u = t + R m - b."""
    R = rotation_matrices(np.asarray(pose)[3:], geometry.euler)
    u = pose[:3] + R @ geometry.m[leg] - geometry.b[leg]
    return u / np.linalg.norm(u)


def test_singular_hooke_axis_raises():
    g = reference_fixture()
    p = table_pose("P5")
    # base axis of leg 3 along its strut at P5: singular at P5, fine at home
    axes = g.base_axes.copy()
    axes[2] = strut_axis(g, p, leg=2)
    bad = FloatingNutKinematics(g.with_changes(base_axes=axes))
    with pytest.raises(SingularHookeError, match="leg 3") as info:
        bad.ik(np.vstack([g.p0, p]))
    assert info.value.sample == 1 and info.value.leg == 2
    assert isinstance(info.value, AssemblyError)
    # platform axis along the strut at home: the constructor says so
    axes = g.plat_axes.copy()
    axes[0] = strut_axis(g, g.p0, leg=0)
    with pytest.raises(SingularHookeError, match="home pose"):
        FloatingNutKinematics(g.with_changes(plat_axes=axes))


def test_fk_failure_is_a_clear_error(kin):
    with pytest.raises(AssemblyError) as info:
        kin.fk(np.full(6, 0.01), max_iter=20)    # 1 cm struts cannot reach a 0.4 m platform
    assert isinstance(info.value, (FKNotConverged, SingularHookeError))
    assert "sample 0" in str(info.value)


def test_motor_maps(kin):
    g = reference_fixture().with_changes(gear_ratio=3.0)
    k = FloatingNutKinematics(g)
    lengths = k.home_lengths + np.array([0.01, -0.02, 0.0, 0.005, 0.03, -0.01])
    psi = k.lengths_to_motor(lengths)
    np.testing.assert_allclose(psi[0], 0.01 / 0.01 * 2 * np.pi * 3.0, rtol=1e-12)   # 1 screw rev = 1 lead
    np.testing.assert_allclose(k.motor_to_lengths(psi), lengths, atol=1e-15)
    with pytest.raises(InputError, match="zero lead"):
        FloatingNutKinematics(g.with_changes(lead=0.0)).lengths_to_motor(lengths)


def test_other_euler_convention_round_trip():
    g = reference_fixture().with_changes(euler="XYZ-moving", p0=[0.01, -0.02, 0.8, 2 * DEG, -3 * DEG, 5 * DEG])
    k = FloatingNutKinematics(g)
    assert np.all(k.nut_rotation(g.p0) == 0)
    poses = random_poses(g, 200, seed=11)
    res = k.fk(k.ik(poses))
    assert np.abs(res.pose - poses).max() < 1e-12 and res.iterations.max() <= 4


@pytest.mark.parametrize("change, field", [
    (dict(sigma=[1, 1, 0, 1, 1, 1]), "sigma"),
    (dict(lead=-0.01), "lead"),
    (dict(b=np.zeros((5, 3))), "b"),
    (dict(base_axes=np.zeros((6, 3))), "base_axes"),
    (dict(euler="ZXZ"), "euler"),
    (dict(p0=[0, 0, np.nan, 0, 0, 0]), "p0"),
])
def test_bad_geometry_is_named(change, field):
    with pytest.raises(InputError) as info:
        reference_fixture().with_changes(**change)
    assert info.value.field == field


def test_bad_pose_input(kin):
    with pytest.raises(InputError, match="shape"):
        kin.ik(np.zeros((3, 5)))
    with pytest.raises(InputError) as info:
        kin.ik([[0, 0, 0.8, 0, 0, 0], [0, 0, np.inf, 0, 0, 0]])
    assert info.value.row == 1
    with pytest.raises(InputError, match="jacobian"):
        kin.fk(kin.home_lengths, jacobian="broyden")
    # the solver options are checked before any path (single pose, batch, compiled) is taken
    for lengths in (kin.home_lengths, np.tile(kin.home_lengths, (2, 1))):
        for bad, field in ((dict(max_iter=None), "max_iter"), (dict(max_iter=-1), "max_iter"),
                           (dict(max_iter=2.5), "max_iter"), (dict(tol=0.0), "tol"), (dict(tol=np.nan), "tol")):
            with pytest.raises(InputError) as info:
                kin.fk(lengths, **bad)
            assert info.value.field == field


@pytest.mark.parametrize("options", [dict(), dict(jacobian="uncompensated"), dict(compensate=False)],
                         ids=["full", "quasi", "uncompensated"])
def test_single_pose_fk_follows_the_batch_iterates(kin, options):
    """One pose at a time takes the lean path (floating_nut_fk.py): same iterations and histories as
    the batch Newton, poses equal to round-off, cold and warm."""
    poses = random_poses(kin.geometry, 200, seed=12)
    lengths = kin.ik(poses, compensate=options.get("compensate", True))
    for p_init in (None, poses + 1e-4):
        batch = kin.fk(lengths, p_init=p_init, **options)
        for k in range(200):
            one = kin.fk(lengths[k], p_init=None if p_init is None else p_init[k], **options)
            assert one.iterations == batch.iterations[k]
            assert np.abs(one.pose - batch.pose[k]).max() < 1e-14
            assert np.abs(one.pose - poses[k]).max() < 1e-12 and one.residual < 1e-12
            assert len(one.history) == one.iterations + 1 and one.history[-1] == one.residual
    assert kin.fk(lengths[0], **options).iterations <= (4 if not options else 6)


def test_single_pose_fk_errors_name_the_sample(kin):
    lengths = kin.ik(table_pose("P5"))
    with pytest.raises(FKNotConverged, match="sample 0 did not converge in 2 iterations"):
        kin.fk(lengths, max_iter=2)
    with pytest.raises(FKNotConverged, match="sample 0 did not converge in 0 iterations"):
        kin.fk(lengths, max_iter=0)
    assert kin.fk(kin.home_lengths).iterations == 0
    # lengths whose uncompensated solution puts leg 3's base axis along its strut
    g = reference_fixture()
    axes = g.base_axes.copy()
    axes[2] = strut_axis(g, table_pose("P5"), leg=2)
    bad = FloatingNutKinematics(g.with_changes(base_axes=axes))
    for lengths in (bad.effective_lengths(table_pose("P5")), bad.effective_lengths(table_pose("P5")[None])):
        with pytest.raises(SingularHookeError, match="leg 3"):
            bad.fk(lengths, compensate=False)


def test_single_pose_fk_condition_warning(kin, caplog):
    lengths = kin.ik(table_pose("P4"))
    with caplog.at_level("WARNING"):
        kin.fk(lengths)
        assert not caplog.records
        kin.fk(lengths, warn_condition=1.0)     # cond(J_c) ~ 5 here: over a threshold of 1
    assert "condition number" in caplog.text


def test_single_pose_rotations_match_the_geometry_conventions():
    from robocal.systems.floating_nut.fk import ROTATIONS
    rng = np.random.default_rng(13)
    for euler, rotation in ROTATIONS.items():
        for angles in rng.uniform(-0.5, 0.5, (5, 3)):
            R, *dR = rotation(*angles)
            np.testing.assert_allclose(np.reshape(R, (3, 3)), rotation_matrices(angles, euler), atol=1e-15)
            for k in range(3):
                h = np.eye(3)[k] * 1e-6
                fd = (rotation_matrices(angles + h, euler) - rotation_matrices(angles - h, euler)) / 2e-6
                np.testing.assert_allclose(np.reshape(dR[k], (3, 3)), fd, atol=1e-9)
