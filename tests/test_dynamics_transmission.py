"""Transmissions, motor-side rows and kHz rate reduction (docs/dynamics_motors.md): the torque map's transpose
convention on the TIAGo wrist's logged relations, the two config forms, the motor rows' regressor against a
direct simulation and the side file's model, the rate reduction in blocks against the whole log at once."""
import numpy as np
import pytest

from robocal import load_example
from robocal.dynamics.channels import Channels, channel_regressor
from robocal.dynamics.effort_map import EffortMap
from robocal.dynamics.identified_model import IdentifiedDynamics, predict_torques
from robocal.dynamics.inertial import parameter_vector
from robocal.dynamics.log_loading import JointLog, load_joint_log, reduce_joint_log
from robocal.dynamics.motor_simulation import MotorTerms, excitation, motor_torques, perturbed_model
from robocal.dynamics.rate_reduction import RateReducer, anti_alias_taps
from robocal.dynamics.reduced_model import reduced_model
from robocal.dynamics.transmission import Transmission
from robocal.dynamics.transmission_config import transmission_from_config

WRIST = Transmission(["arm_6_joint", "arm_7_joint"], ["m6", "m7"], [[-0.5, 0.5], [0.5, 0.5]], [0.1, -0.2])


def test_the_tiago_wrist_relations_follow_from_the_position_map():
    rng = np.random.default_rng(0)
    m, e, mdot = rng.normal(size=(3, 50, 2))
    q = WRIST.joint_positions(m)
    assert np.allclose(q[:, 0], (m[:, 1] - m[:, 0]) / 2 + 0.1) and np.allclose(q[:, 1], (m[:, 0] + m[:, 1]) / 2 - 0.2)
    tau = WRIST.joint_torques(e)                 # tau = T^-T e: the relations the TIAGo controller's log satisfies
    assert np.allclose(tau[:, 0], e[:, 1] - e[:, 0]) and np.allclose(tau[:, 1], e[:, 0] + e[:, 1])
    qdot = mdot @ WRIST.matrix.T                 # power: what the motors deliver the joints absorb
    assert np.allclose(np.sum(tau * qdot, axis=1), np.sum(e * mdot, axis=1))
    assert np.allclose(WRIST.motor_positions(q), m) and WRIST.motors_of_joint_torque("arm_6_joint") == ["m6", "m7"]


def test_ratio_and_coupling_is_the_matrix_they_describe():
    joints = ["j1", "j2", "j3"]
    by_ratio = transmission_from_config({"motors": {"a": "j1", "b": "j2", "c": "j3"}, "ratio": {"a": 100, "b": 50,
                                         "c": -80}, "coupling": {"j3": {"b": 0.004}}, "effort": "torque"}, joints, None,
                                        "cfg")
    by_matrix = transmission_from_config({"motors": ["a", "b", "c"], "matrix": [[0.01, 0, 0], [0, 0.02, 0],
                                                                                [0, 0.004, -0.0125]],
                                          "effort": "torque"}, joints, None, "cfg")
    assert np.allclose(by_ratio.matrix, by_matrix.matrix) and by_ratio.motor_constant is None
    back = Transmission.from_dict(by_ratio.to_dict(), "side")
    assert np.array_equal(back.matrix, by_ratio.matrix) and back.motors == ["a", "b", "c"]


@pytest.fixture(scope="module")
def ur5_coupled():
    robot = load_example("ur5")
    model = reduced_model(robot.urdf_path, robot.joint_names)
    matrix = np.eye(6) / 100
    matrix[5, 4] = 0.003                          # joint 6 turned by motor 5 too
    tr = Transmission(robot.joint_names, [f"motor_{i}" for i in range(1, 7)], matrix, np.linspace(-0.2, 0.3, 6),
                      np.full(6, 0.1))
    terms = MotorTerms(np.linspace(2e-5, 8e-5, 6), np.linspace(0.02, 0.05, 6), np.linspace(1e-4, 4e-4, 6),
                       np.linspace(-0.01, 0.01, 6))
    return model, tr, terms


def test_the_motor_rows_are_the_motors_torques(ur5_coupled):
    model, tr, terms = ur5_coupled
    truth = perturbed_model(model, 3)
    t = np.linspace(0, 4, 200)
    q, v, a = excitation(t, model, 5)
    width = np.full(6, 3.0)
    logged = ["motor_2", "motor_5", "motor_6"]    # a part of the motors logged: their rows only
    channels = Channels.of_motors(model, tr, logged, ("coulomb", "viscous", "offset", "armature"))
    reg = channel_regressor(model, q, v, a, channels, {}, np.ones(3), width[[1, 4, 5]])
    idx = [tr.motors.index(m) for m in logged]
    params = np.r_[parameter_vector(truth), np.concatenate([[terms.values(k)[i] for k in channels.motor_terms]
                                                            for i in idx])]
    direct = motor_torques(truth, tr, terms, q, v, a, width)[:, idx]
    assert np.allclose((reg.X @ params).reshape(-1, 3), direct, rtol=1e-10, atol=1e-12)
    # the side file's model (identified_model.py) predicts the same from the URDF's bodies and its terms
    dyn = IdentifiedDynamics("x.urdf", list(tr.joints), EffortMap(logged, np.full(3, 0.1), np.zeros(3)),
                             {}, {m: 3.0 for m in logged}, {m: 0.0 for m in logged}, {}, tr,
                             {m: {k: float(terms.values(k)[tr.motors.index(m)]) for k in channels.motor_terms}
                              for m in logged})
    assert np.allclose(predict_torques(truth, dyn, q, v, a), direct, rtol=1e-10, atol=1e-12)
    # joint 6's torque needs motors 5 and 6, joint 5's motor 5 alone (tau = T^-T tau_m), joint 2's motor 2
    names, _, to_joints = channels.joint_map(model)
    assert names == ["shoulder_lift_joint", "wrist_2_joint", "wrist_3_joint"]


def test_a_joint_term_its_single_motor_holds_is_left_to_the_motor(ur5_coupled):
    model, tr, _ = ur5_coupled
    channels = Channels.of_motors(model, tr, tr.motors, ("coulomb", "offset"))
    terms, notes = channels.joint_terms(model, ("coulomb", "viscous", "offset"))
    assert terms[0] == ("viscous",) and terms[5] == ("coulomb", "viscous")    # joint 6: two motors, not the same
    assert len(notes) == 6 and "left to the motors'" in notes[0]


def test_the_rate_reduction_in_blocks_is_the_whole_log_filtered_at_once():
    rng = np.random.default_rng(1)
    fs, r = 5000.0, 20
    t = np.arange(30011) / fs
    x = np.column_stack([np.sin(2 * np.pi * 10 * t), np.sin(2 * np.pi * 240 * t), rng.normal(size=len(t))])
    reducer = RateReducer(r, [0])
    sizes = []
    for start in range(0, len(t), 4096):
        reducer.push(x[start:start + 4096])
        sizes.append(len(reducer._buffer))
    rows, out, raw = reducer.finish()
    taps = anti_alias_taps(r)
    reach = (len(taps) - 1) // 2
    whole = np.array([taps @ x[p - reach:p + reach + 1][::-1] for p in rows])
    assert np.allclose(out, whole, atol=1e-12) and np.array_equal(raw[:, 0], x[rows, 0])
    assert rows[0] == reach and rows[-1] + reach < len(t) <= rows[-1] + reach + r and np.all(np.diff(rows) == r)
    assert max(sizes) <= 4096 + 2 * reach              # memory: one block plus the filter's reach
    assert np.max(np.abs(out[:, 0] - x[rows, 0])) < 1e-4      # 10 Hz: pass band
    assert np.max(np.abs(out[:, 1])) < 1e-4                   # 240 Hz would fold onto 10 Hz at 250 Hz: stopped


def test_a_khz_joint_log_without_time_column_is_reduced(tmp_path):
    t = np.arange(10000) / 2000.0
    q = np.column_stack([np.sin(t), np.cos(2 * t)])
    log = JointLog(t, q, np.gradient(q, t, axis=0), q + 1.0, ["a", "b"], {"position": "p.csv"})
    reduced, raw, choices = reduce_joint_log(log, 250.0)
    assert "reduced by 8 to 250 Hz" in choices[0] and np.allclose(np.diff(reduced.t), 1 / 250)
    assert np.allclose(reduced.q, np.column_stack([np.sin(reduced.t), np.cos(2 * reduced.t)]), atol=1e-6)
    assert np.array_equal(raw, (q + 1.0)[np.round(reduced.t * 2000).astype(int)])


def test_a_joint_log_without_time_column_takes_its_sample_period(tmp_path):
    t = np.arange(3000) / 1000.0
    files = {}
    for kind, values in (("position", np.sin(t)), ("velocity", np.cos(t)), ("effort", 2 * np.sin(t))):
        files[kind] = tmp_path / f"{kind}.csv"
        np.savetxt(files[kind], values[:, None], header=f"- a_{kind}", comments="", fmt="%.17g")
    log = load_joint_log(files, ["a"], patterns=None, sample_period=0.001)
    assert np.allclose(log.t, t) and np.allclose(log.effort[:, 0], 2 * np.sin(t))
    reduced, _, choices = reduce_joint_log(log, 250.0)            # 1 kHz: reduced by 4
    assert "reduced by 4" in choices[0] and np.allclose(reduced.q[:, 0], np.sin(reduced.t), atol=1e-6)
