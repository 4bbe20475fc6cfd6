"""Spec seed-004 tests E1-E6, E8: external torque and wrench from motor currents."""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.differentiation import differentiate
from robocal.dynamics.external_force import ExternalForceEstimator
from robocal.dynamics.friction import FrictionModel
from robocal.dynamics.joint_state import from_measurements, from_setpoints
from robocal.errors import InputError

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@pytest.fixture(scope="module")
def ur5():
    return robocal.load_example("ur5")


def ur5_actuator(offset=True):
    return ActuatorModel(torque_constant=[0.12, 0.12, 0.11, 0.09, 0.09, 0.08],
                         gear_ratio=[101, 101, 101, 101, 101, 101],
                         current_offset=[0.01, -0.02, 0.0, 0.03, 0.0, -0.01] if offset else None)


def ur5_friction():
    return FrictionModel(coulomb=[3.0, 3.0, 2.0, 1.0, 1.0, 0.8], viscous=[5.0, 5.0, 3.0, 1.0, 1.0, 1.0],
                         offset=[0.2, -0.1, 0.1, 0.0, 0.05, 0.0], stribeck=[1.0, 1.0, 0.5, 0.2, 0.2, 0.1],
                         smoothing=0.01)


def env_fext(model, data, q, frame_id, wrench_robot_on_env):
    """fext for rnea: the environment's wrench on the body, in the joint's local frame."""
    pin.framesForwardKinematics(model, data, q)
    oMf = data.oMf[frame_id]
    lwa = pin.SE3(np.eye(3), oMf.translation.copy())
    world = lwa.act(pin.Force(-np.asarray(wrench_robot_on_env)))
    fext = pin.StdVec_Force()
    for j in range(model.njoints):
        fext.append(pin.Force.Zero())
    joint = model.frames[frame_id].parentJoint
    fext[joint] = data.oMi[joint].actInv(world)
    return fext


def well_conditioned_configs(robot, frame_id, rng, count, max_cond=50.0):
    m, d = robot.model, robot.model.createData()
    out = []
    while len(out) < count:
        q = rng.uniform(-np.pi, np.pi, m.nq)
        J = pin.computeFrameJacobian(m, d, q, frame_id, LWA)
        if np.linalg.cond(J) < max_cond:
            out.append(q)
    return np.array(out)


def synthesise(robot, frame_id, q, v, a, wrench, actuator, friction):
    m, d = robot.model, robot.model.createData()
    tau = np.array([pin.rnea(m, d, q[k], v[k], a[k], env_fext(m, d, q[k], frame_id, wrench[k]))
                    for k in range(len(q))])
    return actuator.current(tau + friction.torque(v))


def test_E1_identity_and_sign(ur5):
    rng = np.random.default_rng(1)
    fid = ur5.frame_id("tool0")
    q = well_conditioned_configs(ur5, fid, rng, 20)
    v, a = rng.normal(size=(20, 6)), rng.normal(size=(20, 6))
    wrench = rng.normal(scale=[40, 40, 40, 5, 5, 5], size=(20, 6))
    act, fr = ur5_actuator(), ur5_friction()
    current = synthesise(ur5, fid, q, v, a, wrench, act, fr)
    est = ExternalForceEstimator(ur5.model, fid, act, fr).estimate(q, v, a, current)
    d = ur5.model.createData()
    J = np.array([pin.computeFrameJacobian(ur5.model, d, qk, fid, LWA) for qk in q])
    assert np.max(np.abs(est.joint_torque - np.einsum("kij,ki->kj", J, wrench))) < 1e-9
    assert np.max(np.abs(est.wrench - wrench)) < 1e-9
    assert not est.damped.any()


def test_E1_panda_redundant_least_squares():
    panda = robocal.load_example("panda")
    rng = np.random.default_rng(2)
    fid = panda.frame_id("panda_hand_tcp")
    q = well_conditioned_configs(panda, fid, rng, 5, max_cond=100)
    v, a = rng.normal(size=(5, 9)), rng.normal(size=(5, 9))
    wrench = rng.normal(scale=20, size=(5, 6))
    act, fr = ActuatorModel.identity(9), FrictionModel.none(9)
    current = synthesise(panda, fid, q, v, a, wrench, act, fr)
    est = ExternalForceEstimator(panda.model, fid, act, fr).estimate(q, v, a, current)
    assert np.max(np.abs(est.wrench - wrench)) < 1e-9
    assert np.max(np.abs(est.residual)) < 1e-9      # consistent torques: nothing left over


def test_E2_static_push_on_wall_is_positive(ur5):
    fid = ur5.frame_id("tool0")
    q = np.array([[0.3, -1.2, 1.5, -1.9, -1.5, 0.2]])
    zero = np.zeros((1, 6))
    push = np.array([[50.0, 0, 0, 0, 0, 0]])          # robot pushes +x on the wall
    act = ur5_actuator()
    current = synthesise(ur5, fid, q, zero, zero, push, act, FrictionModel.none(6))
    est = ExternalForceEstimator(ur5.model, fid, act).estimate(q, zero, zero, current)
    assert est.wrench[0, 0] > 0
    assert np.max(np.abs(est.wrench - push)) < 1e-9


def test_E3_noise_covariance_matches_prediction(ur5):
    rng = np.random.default_rng(3)
    fid = ur5.frame_id("tool0")
    q0 = well_conditioned_configs(ur5, fid, rng, 1)[0]
    n = 4000
    q, v, a = np.tile(q0, (n, 1)), np.zeros((n, 6)), np.zeros((n, 6))
    act = ur5_actuator()
    sigma_i = np.array([0.02, 0.02, 0.03, 0.01, 0.01, 0.01])     # A
    clean = synthesise(ur5, fid, q[:1], v[:1], a[:1], np.zeros((1, 6)), act, FrictionModel.none(6))
    current = clean + rng.normal(size=(n, 6)) * sigma_i
    est = ExternalForceEstimator(ur5.model, fid, act).estimate(q, v, a, current)
    J = pin.computeFrameJacobian(ur5.model, ur5.model.createData(), q0, fid, LWA)
    JinvT = np.linalg.inv(J.T)
    predicted = JinvT @ act.gain @ np.diag(sigma_i**2) @ act.gain.T @ JinvT.T
    sample = np.cov(est.wrench.T)
    # standard error of a sample covariance entry: sqrt((C_ii C_jj + C_ij^2) / (n - 1))
    se = np.sqrt((np.outer(np.diag(predicted), np.diag(predicted)) + predicted**2) / (n - 1))
    assert np.all(np.abs(sample - predicted) < 5 * se)
    assert np.all(np.abs(est.wrench.mean(0)) < 5 * np.sqrt(np.diag(predicted) / n))


def test_E4_torque_constant_mismatch_is_linear(ur5):
    rng = np.random.default_rng(4)
    fid = ur5.frame_id("tool0")
    q = well_conditioned_configs(ur5, fid, rng, 10)
    v, a = rng.normal(size=(10, 6)), rng.normal(size=(10, 6))
    wrench = rng.normal(scale=30, size=(10, 6))
    act = ur5_actuator()
    current = synthesise(ur5, fid, q, v, a, wrench, act, FrictionModel.none(6))
    delta = np.array([0.05, -0.03, 0.02, 0.1, -0.08, 0.04])
    wrong = ActuatorModel(act.torque_constant * (1 + delta), act.gear_ratio, act.current_offset)
    est = ExternalForceEstimator(ur5.model, fid, wrong).estimate(q, v, a, current)
    d = ur5.model.createData()
    for k in range(10):
        J = pin.computeFrameJacobian(ur5.model, d, q[k], fid, LWA)
        dtau = delta * act.torque(current[k])          # delta K_t (I - I0)
        expected = np.linalg.solve(J.T, dtau)
        assert np.allclose(est.wrench[k] - wrench[k], expected, rtol=0, atol=1e-9)


def test_E5_friction_uncompensated_then_compensated(ur5):
    rng = np.random.default_rng(5)
    fid = ur5.frame_id("tool0")
    q = well_conditioned_configs(ur5, fid, rng, 10)
    v, a = rng.normal(size=(10, 6)), rng.normal(size=(10, 6))
    wrench = rng.normal(scale=30, size=(10, 6))
    act, fr = ur5_actuator(), ur5_friction()
    current = synthesise(ur5, fid, q, v, a, wrench, act, fr)
    without = ExternalForceEstimator(ur5.model, fid, act).estimate(q, v, a, current)
    with_ = ExternalForceEstimator(ur5.model, fid, act, fr).estimate(q, v, a, current)
    d = ur5.model.createData()
    tau_f = fr.torque(v)
    for k in range(10):
        J = pin.computeFrameJacobian(ur5.model, d, q[k], fid, LWA)
        assert np.allclose(without.wrench[k] - wrench[k], np.linalg.solve(J.T, tau_f[k]), atol=1e-9, rtol=0)
    assert np.max(np.abs(with_.wrench - wrench)) < 1e-9


def sinusoid(t, centre, amp, omega, phase):
    arg = omega * t[:, None] + phase
    return (centre + amp * np.sin(arg), amp * omega * np.cos(arg), -amp * omega**2 * np.sin(arg))


def test_E6_central_differences_within_computed_bound(ur5):
    """0.3 rad, 0.5 Hz sinusoids sampled every 4 ms, 50 N tip force. Central differences:
    |dv| <= dt^2/6 A w^3, |da| <= dt^2/12 A w^4 per joint; pushed through the linearised model
    |dF| <= |J^-T| (|dtau/dv| |dv| + |M| |da|). Second-order terms are O(dv^2) ~ 1e-9 of that."""
    dt, amp, omega = 0.004, 0.3, 2 * np.pi * 0.5
    centre = np.array([0.3, -1.2, 1.5, -1.9, -1.5, 0.2])
    phase = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    t = np.arange(0, 2.0, dt)
    q, v_true, a_true = sinusoid(t, centre, amp, omega, phase)
    fid = ur5.frame_id("tool0")
    push = np.tile([50.0, 0, 0, 0, 0, 0], (len(t), 1))
    act = ur5_actuator()
    current = synthesise(ur5, fid, q, v_true, a_true, push, act, FrictionModel.none(6))
    est = ExternalForceEstimator(ur5.model, fid, act)
    inner = slice(1, -1)                       # end samples use one-sided stencils
    central = from_measurements(q, dt, "central")
    err_c = est.estimate(central.q, central.v, central.a, current).wrench[inner] - push[inner]
    dv_bound = dt**2 / 6 * amp * omega**3
    da_bound = dt**2 / 12 * amp * omega**4
    m, d = ur5.model, ur5.model.createData()
    for k in range(1, len(t) - 1):
        dtau_dq, dtau_dv, M = (x.copy() for x in pin.computeRNEADerivatives(m, d, q[k], v_true[k], a_true[k]))
        J = pin.computeFrameJacobian(m, d, q[k], fid, LWA)
        bound = np.abs(np.linalg.inv(J.T)) @ (np.abs(dtau_dv).sum(1) * dv_bound + np.abs(M).sum(1) * da_bound)
        assert np.all(np.abs(err_c[k - 1]) <= bound * (1 + 1e-3) + 1e-12), k
    backward = from_measurements(q, dt, "backward")
    err_b = est.estimate(backward.q, backward.v, backward.a, current).wrench[2:] - push[2:]
    assert np.max(np.abs(err_b)) > 10 * np.max(np.abs(err_c))   # why the scheme is stated


def test_E8_setpoint_and_measured_variants_agree_with_perfect_tracking(ur5):
    dt, omega = 0.004, 2 * np.pi * 0.5
    t = np.arange(0, 1.0, dt)
    q, v, a = sinusoid(t, np.array([0.3, -1.2, 1.5, -1.9, -1.5, 0.2]), 0.2, omega, np.arange(6.0))
    fid = ur5.frame_id("tool0")
    act = ur5_actuator()
    current = synthesise(ur5, fid, q, v, a, np.zeros((len(t), 6)), act, FrictionModel.none(6))
    est = ExternalForceEstimator(ur5.model, fid, act)
    setpoint = from_setpoints(q, dt, v, a)                 # analytic setpoint derivatives
    measured = from_measurements(q.copy(), dt, "central")  # perfect servo: q_mes == q_des
    f_set = est.estimate(setpoint.q, setpoint.v, setpoint.a, current).wrench
    f_mes = est.estimate(measured.q, measured.v, measured.a, current).wrench
    assert setpoint.scheme == "analytic" and measured.source == "measured"
    assert np.max(np.abs(f_set)) < 1e-9                    # exact derivatives: exact zero force
    differentiated = from_setpoints(q, dt)                 # same scheme on the same samples
    f_diff = est.estimate(differentiated.q, differentiated.v, differentiated.a, current).wrench
    assert np.array_equal(f_diff, f_mes)
    assert np.max(np.abs(f_mes[1:-1])) < 1.0               # only the differentiation error remains


def test_tick_matches_batch_and_singularity_is_damped(ur5):
    rng = np.random.default_rng(6)
    fid = ur5.frame_id("tool0")
    q = well_conditioned_configs(ur5, fid, rng, 1)
    v, a, cur = rng.normal(size=(1, 6)), rng.normal(size=(1, 6)), rng.normal(size=(1, 6))
    est = ExternalForceEstimator(ur5.model, fid, ur5_actuator(), ur5_friction())
    batch = est.estimate(q, v, a, cur)
    w, cond = est.tick(q[0], v[0], a[0], cur[0])
    assert np.allclose(w, batch.wrench[0], atol=1e-12) and cond == pytest.approx(batch.condition[0])
    singular = np.array([[0.0, -np.pi / 2, 0.0, -np.pi / 2, 0.0, 0.0]])   # wrist 5 at zero, arm stretched
    res = est.estimate(singular, v, a, cur)
    assert res.damped[0] and res.ill_conditioned[0] and np.all(np.isfinite(res.wrench))
    w_tick, cond_tick = est.tick(singular[0], v[0], a[0], cur[0])     # the per-tick path damps alike
    assert np.allclose(w_tick, res.wrench[0], rtol=1e-9, atol=1e-9) and cond_tick > 1e3


def test_bad_input_is_rejected(ur5):
    est = ExternalForceEstimator(ur5.model, ur5.frame_id("tool0"))
    with pytest.raises(InputError):
        est.estimate(np.zeros((3, 5)), np.zeros((3, 6)), np.zeros((3, 6)), np.zeros((3, 6)))
    with pytest.raises(InputError):
        ActuatorModel([1.0, 0.0])
    with pytest.raises(InputError):
        differentiate(np.zeros((10, 2)), 0.0)
    bad = np.zeros((3, 6)); bad[1, 2] = np.nan
    with pytest.raises(InputError) as info:
        est.estimate(bad, np.zeros((3, 6)), np.zeros((3, 6)), np.zeros((3, 6)))
    assert info.value.row == 1


def test_coupled_wrist_round_trip():
    # UR5's last two joints driven through a differential: joint torques = C @ motor torques
    C = np.eye(6); C[4, 5], C[5, 4] = 0.5, -0.5
    act = ActuatorModel([0.1] * 6, [100] * 6, [0.01] * 6, coupling=C)
    rng = np.random.default_rng(7)
    tau = rng.normal(size=(5, 6))
    assert np.allclose(act.torque(act.current(tau)), tau, atol=1e-12)
    motor = act.current(tau)[0] - act.current_offset
    assert np.allclose(act.torque(act.current(tau))[0], C @ (10.0 * motor), atol=1e-12)
