"""Dynamic identification (spec §12) and test E7: base parameters, friction, torque-constant scale,
payload, excitation trajectories, physical consistency, free-motion force as validation metric."""
import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.excitation import fourier_excitation
from robocal.dynamics.external_force import ExternalForceEstimator
from robocal.dynamics.friction import FrictionModel
from robocal.dynamics.identification import Segment, base_values_of, identify_dynamics, identify_payload
from robocal.dynamics.inertial import parameter_vector, physical_consistency
from robocal.dynamics.payload import payload_inertia, with_payload

DT = 0.01
LOWER = np.array([-2.0, -3.0, -2.5, -2.5, -2.0, -2.0])
UPPER = np.array([2.0, -0.2, 2.5, 2.5, 2.0, 2.0])
QD_MAX, QDD_MAX = np.full(6, 2.0), np.full(6, 6.0)
TERMS = ("coulomb", "viscous", "offset")
SIGMA_I = np.array([0.01, 0.01, 0.01, 0.02, 0.02, 0.02])     # A, current noise


@pytest.fixture(scope="module")
def ur5():
    return robocal.load_example("ur5")


def nominal_actuator():
    return ActuatorModel([0.12, 0.12, 0.11, 0.09, 0.09, 0.08], [101] * 6)


def true_friction():
    return FrictionModel([3, 3, 2, 1, 1, 0.8], [5, 5, 3, 1, 1, 1], offset=[0.2, -0.1, 0.1, 0, 0.05, 0],
                         smoothing=0.01)


def excitation_log(seed, duration=10.0):
    tr = fourier_excitation(LOWER, UPPER, QD_MAX, QDD_MAX, np.random.default_rng(seed), 0.1, 5)
    return tr.sample(np.arange(0, duration, DT))


def currents(model, q, v, a, actuator, friction, rng=None, sigma=None):
    d = model.createData()
    tau = np.array([pin.rnea(model, d, q[k], v[k], a[k]) for k in range(len(q))]) + friction.torque(v)
    i = actuator.current(tau)
    return i if rng is None else i + rng.normal(size=i.shape) * sigma


def true_full(model, friction):
    return np.r_[parameter_vector(model), friction.parameters[:, :3].reshape(-1)]


def test_noise_free_recovery_of_base_parameters(ur5):
    q, v, a = excitation_log(1)
    act, fr = nominal_actuator(), true_friction()
    res = identify_dynamics(ur5.model, [Segment(q, v, a, currents(ur5.model, q, v, a, act, fr))], act, fr, TERMS)
    truth = base_values_of(res.selection, true_full(ur5.model, fr))
    assert res.selection.rank == 36 + 18          # UR5: 36 inertial base parameters + 3 friction per joint
    assert np.linalg.norm(res.base_values - truth) <= 1e-8 * np.linalg.norm(truth)
    assert np.allclose(res.friction.parameters[:, :3], fr.parameters[:, :3], rtol=1e-8, atol=1e-8)


def test_noisy_recovery_within_predicted_standard_errors(ur5):
    rng = np.random.default_rng(2)
    q, v, a = excitation_log(3, 20.0)
    act, fr = nominal_actuator(), true_friction()
    cur = currents(ur5.model, q, v, a, act, fr, rng, SIGMA_I)
    res = identify_dynamics(ur5.model, [Segment(q, v, a, cur)], act, fr, TERMS, current_noise=SIGMA_I)
    truth = base_values_of(res.selection, true_full(ur5.model, fr))
    z = (res.base_values - truth) / res.base_std
    p = len(z)
    assert np.all(np.abs(z) < 5)
    # sum of squared normalised errors is chi-square with p degrees of freedom: mean p, std sqrt(2p)
    assert abs(np.sum(z**2) - p) < 5 * np.sqrt(2 * p)
    assert np.allclose(res.residual_rms, res.sigma_torque, rtol=0.1)   # weights match the noise


def test_scale_unobservable_without_reference_then_fixed_by_payload(ur5):
    rng = np.random.default_rng(4)
    nominal = nominal_actuator()
    alpha = np.array([1.07, 0.95, 1.02, 1.10, 0.93, 1.04])          # true K_t = alpha * nominal
    true_act = ActuatorModel(nominal.torque_constant * alpha, nominal.gear_ratio)
    fr = true_friction()
    q, v, a = excitation_log(5, 20.0)
    free = Segment(q, v, a, currents(ur5.model, q, v, a, true_act, fr, rng, SIGMA_I))
    alone = identify_dynamics(ur5.model, [free], nominal, fr, TERMS, scale="per_joint", current_noise=SIGMA_I)
    assert not alone.scale_observable and "not observable" in alone.message
    assert np.all(alone.scale == 1.0) and np.all(np.isnan(alone.scale_std))
    fid = ur5.frame_id("tool0")
    load = payload_inertia(5.0, [0.02, -0.03, 0.08], np.diag([0.02, 0.03, 0.01]))
    loaded_model = with_payload(ur5.model, fid, load)
    q2, v2, a2 = excitation_log(6, 20.0)
    loaded = Segment(q2, v2, a2, currents(loaded_model, q2, v2, a2, true_act, fr, rng, SIGMA_I), load, fid)
    # currents are read with the nominal constants, so identification sees alpha * tau
    res = identify_dynamics(ur5.model, [free, loaded], nominal, fr, TERMS, scale="per_joint", current_noise=SIGMA_I)
    assert res.scale_observable
    assert np.all(np.abs(res.scale - alpha) < 5 * res.scale_std)
    truth = base_values_of(res.selection, true_full(ur5.model, fr))
    assert np.all(np.abs(res.base_values - truth) < 5 * res.base_std)


def test_payload_identification(ur5):
    rng = np.random.default_rng(7)
    act, fr = nominal_actuator(), true_friction()
    fid = ur5.frame_id("tool0")
    load = payload_inertia(3.0, [0.01, -0.02, 0.06], np.diag([0.01, 0.012, 0.008]))
    q, v, a = excitation_log(8, 20.0)
    cur = currents(with_payload(ur5.model, fid, load), q, v, a, act, fr, rng, SIGMA_I)
    res = identify_payload(ur5.model, fid, Segment(q, v, a, cur), act, fr, SIGMA_I)
    truth = load.toDynamicParameters()
    ok = ~np.isnan(res.std)
    assert {"payload.m", "payload.mx", "payload.my", "payload.mz"} <= set(res.identifiable)
    assert np.all(np.abs(res.params[ok] - truth[ok]) < 5 * res.std[ok])
    assert res.mass == pytest.approx(3.0, abs=5 * res.std[0])


def test_excitation_stays_within_limits_and_derivatives_are_exact():
    tr = fourier_excitation(LOWER, UPPER, QD_MAX, QDD_MAX, np.random.default_rng(9), 0.1, 5)
    t = np.linspace(0, tr.period, 20011)                 # denser than the grid used for scaling
    q, v, a = tr.sample(t)
    assert np.all(q >= LOWER + 0.1 - 1e-9) and np.all(q <= UPPER - 0.1 + 1e-9)
    assert np.all(np.abs(v) <= QD_MAX * (1 + 1e-6)) and np.all(np.abs(a) <= QDD_MAX * (1 + 1e-6))
    h = 1e-5
    tm, tp = t[:50] - h, t[:50] + h
    (qm, vm, _), (qp, vp, _) = tr.sample(tm), tr.sample(tp)
    assert np.allclose((qp - qm) / (2 * h), v[:50], atol=1e-7)
    assert np.allclose((vp - vm) / (2 * h), a[:50], atol=1e-6)
    assert np.allclose(tr.sample(np.array([0.0]))[0], tr.sample(np.array([tr.period]))[0], atol=1e-12)


def test_physical_consistency_check(ur5):
    res_ok = physical_consistency(ur5.model, parameter_vector(ur5.model))
    assert all(val > 0 for val in res_ok.values())
    bad = parameter_vector(ur5.model)
    bad[10] = -1.0                                       # negative mass on the second body
    assert physical_consistency(ur5.model, bad)["shoulder_lift_joint"] < 0


def test_E7_free_motion_force_within_threshold_from_calibration_residuals(ur5):
    rng = np.random.default_rng(10)
    act, fr = nominal_actuator(), true_friction()
    q, v, a = excitation_log(11, 20.0)
    res = identify_dynamics(ur5.model, [Segment(q, v, a, currents(ur5.model, q, v, a, act, fr, rng, SIGMA_I))],
                            act, fr, TERMS)                        # noise level estimated from residuals
    identified = res.model(ur5.model)
    fid = ur5.frame_id("tool0")
    qv, vv, av = excitation_log(12, 10.0)                         # new validation motion
    cur = currents(ur5.model, qv, vv, av, act, fr, rng, SIGMA_I)
    est = ExternalForceEstimator(identified, fid, act, res.friction).estimate(qv, vv, av, cur)
    uncompensated = ExternalForceEstimator(identified, fid, act).estimate(qv, vv, av, cur)
    d = ur5.model.createData()
    good = est.condition < 100
    assert good.sum() > 100
    exceed_calibrated, exceed_plain = 0, 0
    for k in np.flatnonzero(good):
        J = pin.computeFrameJacobian(ur5.model, d, qv[k], fid, pin.LOCAL_WORLD_ALIGNED)
        JinvT = np.linalg.inv(J.T)
        threshold = 5 * np.sqrt(np.diag(JinvT @ np.diag(res.residual_rms**2) @ JinvT.T))
        exceed_calibrated += np.any(np.abs(est.wrench[k]) > threshold)
        exceed_plain += np.any(np.abs(uncompensated.wrench[k]) > threshold)
    assert exceed_calibrated == 0
    assert exceed_plain > 0.5 * good.sum()                        # the metric does detect a bad model
