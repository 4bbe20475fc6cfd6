"""Stewart platform: closed-form IK, Newton FK (single and batch), against each other and against
the generic closed-loop assembly of the URDF model."""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.errors import AssemblyError, InputError
from robocal.model.inverse_kinematics import solve_ik
from robocal.model.loops import assemble
from robocal.systems.stewart import fk as stewart_fk, mechanism as st

URDF = Path(__file__).resolve().parents[1] / "urdf"
GEOMETRIES = {"6_6": st.StewartGeometry.spec_6_6, "3_3": st.StewartGeometry.spec_3_3}


def pose_error(a: pin.SE3, b: pin.SE3) -> float:
    return float(np.linalg.norm(pin.log6(a.actInv(b)).vector))


@pytest.fixture(scope="module", params=sorted(GEOMETRIES))
def machine(request):
    return GEOMETRIES[request.param](), robocal.load_urdf(URDF / f"stewart_{request.param}.urdf")


def test_ik_fk_round_trip_on_200_poses(machine):
    geometry, _ = machine
    R, p = st.random_workspace_poses(geometry, 200, np.random.default_rng(0))
    s = st.inverse_kinematics_batch(geometry, R, p)
    worst = max(pose_error(stewart_fk.forward_kinematics(geometry, s[k], sample=k), pin.SE3(R[k], p[k]))
                for k in range(200))
    assert worst < 1e-9
    # the batch solver gives the same poses
    Rb, pb, converged = stewart_fk.forward_kinematics_batch(geometry, s)
    assert converged.all()
    assert np.abs(Rb - R).max() < 1e-9 and np.abs(pb - p).max() < 1e-9


def test_generic_closed_loop_fk_agrees_with_closed_form_ik(machine):
    geometry, robot = machine
    R, p = st.random_workspace_poses(geometry, 200, np.random.default_rng(1))
    s = st.inverse_kinematics_batch(geometry, R, p)
    data = robot.model.createData()
    q = None
    for k in range(200):
        q = assemble(robot, robot.model, s[k], q_guess=q, sample=k, data=data)  # warm start
        assert pose_error(st.platform_pose(robot, robot.model, q, data), pin.SE3(R[k], p[k])) < 1e-10
        np.testing.assert_allclose(robot.loops.actuated_values(q), s[k], atol=1e-15)


def test_generic_ik_agrees_with_closed_form_ik(machine):
    geometry, robot = machine
    R, p = st.random_workspace_poses(geometry, 5, np.random.default_rng(2))
    for k in range(5):
        q = solve_ik(robot.model, robot.frame_id("platform"), pin.SE3(R[k], p[k]), loops=robot.loops, sample=k)
        expected = st.inverse_kinematics(geometry, pin.SE3(R[k], p[k]))
        assert np.abs(robot.loops.actuated_values(q) - expected).max() < 1e-10


def test_ik_jacobian_matches_finite_differences(machine):
    geometry, _ = machine
    R, p = st.random_workspace_poses(geometry, 3, np.random.default_rng(3))
    eps = 1e-6  # central differences: error ~ eps^2 |s'''| + 1e-16 / eps
    for k in range(3):
        M = pin.SE3(R[k], p[k])
        fd = np.column_stack([(st.inverse_kinematics(geometry, M * pin.exp6(eps * e))
                               - st.inverse_kinematics(geometry, M * pin.exp6(-eps * e))) / (2 * eps)
                              for e in np.eye(6)])
        assert np.abs(fd - st.ik_jacobian(geometry, M)).max() < 1e-8


def test_fk_noise_propagation_matches_the_linearised_prediction():
    """Synthetic truth: strut readings with 1 um noise; the FK pose error e must follow
    e ~ N(0, sigma^2 (J^T J)^-1), i.e. e^T J^T J e / sigma^2 ~ chi2(6) (mean 6, var 12)."""
    geometry = st.StewartGeometry.spec_6_6()
    rng = np.random.default_rng(4)
    n, sigma = 2000, 1e-6
    R, p = st.random_workspace_poses(geometry, n, rng)
    s = st.inverse_kinematics_batch(geometry, R, p) + rng.normal(0, sigma, (n, 6))
    Rf, pf, _ = stewart_fk.forward_kinematics_batch(geometry, s, R, p)
    chi2 = np.empty(n)
    for k in range(n):
        M = pin.SE3(R[k], p[k])
        e = pin.log6(M.actInv(pin.SE3(Rf[k], pf[k]))).vector
        J = st.ik_jacobian(geometry, M)
        chi2[k] = e @ J.T @ J @ e / sigma**2
    assert abs(chi2.mean() - 6.0) < 5 * np.sqrt(12.0 / n)


def test_unreachable_struts_raise_assembly_error_naming_the_sample(machine):
    geometry, robot = machine
    s = st.inverse_kinematics(geometry, geometry.home_pose)
    s[0] += 2.0  # one strut 2 m longer than the others allow
    with pytest.raises(AssemblyError, match="sample 17"):
        stewart_fk.forward_kinematics(geometry, s, sample=17)
    with pytest.raises(AssemblyError, match="sample 17"):
        assemble(robot, robot.model, s, sample=17)
    with pytest.raises(AssemblyError, match=r"samples \[1\]"):
        stewart_fk.forward_kinematics_batch(geometry, np.vstack([s - [2.0, 0, 0, 0, 0, 0], s]))


def test_singular_pose_raises_assembly_error():
    # the 3-3 (octahedral) platform is singular when turned 90 deg about its axis
    geometry = st.StewartGeometry.spec_3_3()
    robot = robocal.load_urdf(URDF / "stewart_3_3.urdf")
    singular = pin.SE3(pin.rpy.rpyToMatrix(0, 0, np.pi / 2), geometry.home)
    assert np.linalg.cond(st.ik_jacobian(geometry, singular)) > 1e12
    s = st.inverse_kinematics(geometry, singular)
    guess = singular * pin.exp6(np.array([0, 0, 0.01, 0, 0, 0.05]))
    with pytest.raises(AssemblyError, match="sample 3: .*singular"):
        stewart_fk.forward_kinematics(geometry, s, guess=guess, sample=3)
    with pytest.raises(AssemblyError, match="sample 3: .*singular"):
        assemble(robot, robot.model, s, q_guess=st.configuration_from_pose(robot, geometry, guess), sample=3)


def test_closed_chain_fk_jacobian_inverts_the_ik_jacobian(machine):
    """Implicit-function theorem through the generic loops: d(platform twist)/ds = (ds/dxi)^-1."""
    geometry, robot = machine
    model, loops = robot.model, robot.loops
    data = model.createData()
    M = pin.SE3(st.rotation_xyz([0.1, -0.05, 0.2]), geometry.home + [0.03, -0.02, 0.05])
    q = st.configuration_from_pose(robot, geometry, M)
    _, jac = loops.constraint_jacobian(model, data, q)
    dv_ds = np.zeros((model.nv, 6))
    dv_ds[loops.actuated_v] = np.eye(6)
    dv_ds[loops.passive_v] = -np.linalg.solve(jac[:, loops.passive_v], jac[:, loops.actuated_v])
    j_platform = pin.getFrameJacobian(model, data, robot.frame_id("platform"), pin.ReferenceFrame.LOCAL)
    assert np.abs(j_platform @ dv_ds @ st.ik_jacobian(geometry, M) - np.eye(6)).max() < 1e-10


def test_parameters_map_onto_placements_of_a_calibrated_copy(machine):
    """N = u1 placement translation, T = leg{j}_top.link2 frame translation, o = slide placement z:
    after editing those in a model copy, closed form and generic assembly still agree."""
    geometry, robot = machine
    rng = np.random.default_rng(5)
    model = robot.model.copy()
    for j in range(6):
        leg = f"leg{j + 1}"
        u1, slide = robot.joint_id(f"{leg}_u1"), robot.joint_id(f"{leg}_slide")
        model.jointPlacements[u1].translation = model.jointPlacements[u1].translation + rng.normal(0, 1e-3, 3)
        slide_origin = model.jointPlacements[slide].translation
        model.jointPlacements[slide].translation = slide_origin + [0, 0, 1e-3 * rng.normal()]
        f2 = model.frames[robot.frame_id(f"{leg}_top.link2")]
        f2.placement.translation = f2.placement.translation + rng.normal(0, 1e-3, 3)
        model.frames[robot.frame_id(f"{leg}_top.link2")] = f2
    calibrated = st.geometry_from_model(robot, model)
    nominal = st.geometry_from_model(robot)
    assert np.abs(calibrated.leg_base - nominal.leg_base).max() > 1e-4  # the edits were read
    np.testing.assert_allclose(nominal.leg_base, geometry.leg_base, atol=1e-15)
    np.testing.assert_allclose(nominal.leg_platform, geometry.leg_platform, atol=1e-15)
    np.testing.assert_allclose(nominal.offsets, geometry.offsets, atol=1e-15)
    R, p = st.random_workspace_poses(geometry, 10, rng)
    s = st.inverse_kinematics_batch(calibrated, R, p)
    data = model.createData()
    for k in range(10):
        q = assemble(robot, model, s[k], sample=k, data=data)
        assert pose_error(st.platform_pose(robot, model, q, data), pin.SE3(R[k], p[k])) < 1e-10


def test_geometry_from_model_refuses_edits_the_closed_form_cannot_describe(machine):
    _, robot = machine
    model = robot.model.copy()
    u2 = robot.joint_id("leg3_u2")
    model.jointPlacements[u2] = pin.SE3(np.eye(3), np.array([0.0, 0.001, 0.0]))
    with pytest.raises(InputError, match="leg3_u2"):
        st.geometry_from_model(robot, model)


def test_geometry_validates_its_input():
    with pytest.raises(InputError):
        st.StewartGeometry(np.zeros((6, 3)), np.zeros((6, 3)), [(k, k) for k in range(5)], np.zeros(5))
    with pytest.raises(InputError):
        st.StewartGeometry(np.zeros((3, 3)), np.zeros((3, 3)), [(k, k) for k in range(6)], np.zeros(6))
    geometry = st.StewartGeometry.spec_6_6()
    with pytest.raises(ValueError):  # immutable: a calibrated geometry is a new object
        geometry.offsets[0] = 1.0


def test_rotation_convention_is_rx_ry_rz():
    a, b, c = 0.1, -0.2, 0.3
    rx = pin.rpy.rpyToMatrix(a, 0, 0)
    ry = pin.rpy.rpyToMatrix(0, b, 0)
    rz = pin.rpy.rpyToMatrix(0, 0, c)
    np.testing.assert_allclose(st.rotation_xyz([a, b, c]), rx @ ry @ rz, atol=1e-15)
    batch = st.rotation_xyz(np.array([[a, b, c], [0, 0, 0]]))
    np.testing.assert_allclose(batch[0], rx @ ry @ rz, atol=1e-15)
    np.testing.assert_allclose(batch[1], np.eye(3), atol=1e-15)


def test_newton_tables_give_strut_vectors_and_jacobian(machine):
    """One product of the (54, 16) table with the inverse pose gives l_j and 2 J_u (stored transposed)."""
    geometry, _ = machine
    lift = geometry._fk.lift
    R, p = st.random_workspace_poses(geometry, 5, np.random.default_rng(6))
    for k in range(5):
        M = pin.SE3(R[k], p[k])
        out = lift @ M.inverse().homogeneous.ravel()
        d = st.local_strut_vectors(geometry, R[k:k + 1], p[k:k + 1])[0]
        np.testing.assert_allclose(out[:18].reshape(6, 3), d, atol=1e-15)
        unnormalised = st.ik_jacobian(geometry, M) * np.linalg.norm(d, axis=1)[:, None]
        np.testing.assert_allclose(out[18:].reshape(6, 6).T, 2 * unnormalised, atol=1e-14)


def test_single_fk_newton_solves_and_strut_residual(machine, monkeypatch):
    """Cold start: at most 4 Newton solves after the precomputed home step; the returned pose meets
    the strut-length tolerance; an exact guess is returned after one factorisation (singularity check)."""
    geometry, _ = machine
    R, p = st.random_workspace_poses(geometry, 300, np.random.default_rng(7))
    s = st.inverse_kinematics_batch(geometry, R, p)
    calls = []
    solve = stewart_fk.dgesv
    monkeypatch.setattr(stewart_fk, "dgesv", lambda *a: calls.append(1) or solve(*a))
    worst = 0.0
    for k in range(300):
        calls.clear()
        pose = stewart_fk.forward_kinematics(geometry, s[k], sample=k)
        assert len(calls) <= 4
        worst = max(worst, np.linalg.norm(st.inverse_kinematics(geometry, pose) - s[k]))
    assert worst < 1e-12
    calls.clear()
    exact = pin.SE3(R[0], p[0])
    assert pose_error(stewart_fk.forward_kinematics(geometry, s[0], guess=exact), exact) < 1e-15
    assert len(calls) == 1


def test_non_positive_strut_length_raises_naming_the_sample(machine):
    geometry, _ = machine
    s = st.inverse_kinematics(geometry, geometry.home_pose)
    s[2] = -geometry.offsets[2] - 0.1    # o + s < 0: |l| = o + s has no solution (its square would)
    with pytest.raises(AssemblyError, match="sample 4: .*non-positive"):
        stewart_fk.forward_kinematics(geometry, s, sample=4)
