"""Calibrating the floating-nut hexapod through the generic layer (issue #5 part 4, spec seed-002 §7.6).

The URDF's `<screw_transmission>` rows are enforced by assembly: the encoder reading is the command
length, and the nut roll the Hooke joints impose adds sigma L/2pi theta to the strut. The truth machine
differs from the nominal one in its Hooke centres, encoder zeros and leads; it is observed by a 6D tracker
on the platform.
"""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.estimation.calibrate import calibrate
from robocal.errors import InputError
from robocal.model.urdf_export import calibrated_urdf
from robocal.systems.floating_nut.calibration import choose_thread_hands, floating_nut_parameters, uncompensated_robot
from robocal.model.kinematics import ModelState
from robocal.systems.floating_nut.geometry import reference_fixture, rotation_matrices
from robocal.systems.floating_nut.kinematics import FloatingNutKinematics
from robocal.model.parameters import Parameter, ParameterSet
from robocal.estimation.problem import Problem
from robocal.residuals import PoseResidual
from robocal.design.simulate import simulate_measurements
from robocal.testing import assert_calibration_recovers, assert_frame_jacobians, assert_problem_jacobian

URDF = Path(__file__).resolve().parents[1] / "urdf" / "floating_nut_hexapod.urdf"
SIGMA = (1e-5, 1e-5)          # tracker: 10 um, 10 urad
GEOMETRY = reference_fixture()
KIN = FloatingNutKinematics(GEOMETRY)


@pytest.fixture(scope="module")
def robot():
    return robocal.load_urdf(URDF)


def workspace(n, rng, reach=0.08, tilt_deg=10.0):
    """Platform poses around home and their encoder readings (command lengths from home)."""
    poses = GEOMETRY.p0 + np.column_stack([rng.uniform(-reach, reach, (n, 3)),
                                           np.deg2rad(rng.uniform(-tilt_deg, tilt_deg, (n, 3)))])
    return poses, KIN.ik(poses) - KIN.ik(GEOMETRY.p0)


def tracker_problem(robot, params, readings):
    n = len(readings)
    start = np.tile([0, 0, 0.8, 0, 0, 0, 1.0], (n, 1))
    return Problem(robot, params, robot.loops.actuated, readings,
                   [PoseResidual("platform_pose", "platform", np.arange(n), start, sigma=SIGMA)])


def perturbed_truth(robot, rng, leads=True, **kwargs):
    truth = floating_nut_parameters(robot, **kwargs)
    for p in truth:
        if p.vary:
            p.value += rng.normal(0, 2e-5 if p.name.endswith(".lead") else 1e-3)   # lead: 0.2 % of 10 mm
    if not leads:
        for p in truth:
            if p.name.endswith(".lead"):
                p.value = 0.01
    return truth


def test_screw_rows_make_the_generic_assembly_the_compensated_kinematics(robot):
    """Readings = compensated command lengths: the generic closed chain puts the platform at the pose and
    the nut roll joint at the spec's theta; the uncompensated chain misses by the additional length."""
    poses, readings = workspace(20, np.random.default_rng(1))
    ms = ModelState(robot, ParameterSet(), robot.loops.actuated)
    plain = ModelState(uncompensated_robot(robot), ParameterSet(), robot.loops.actuated)
    roll_q = [robot.model.joints[robot.joint_id(f"leg{i}_nut_roll")].idx_q for i in range(1, 7)]
    miss = []
    for pose, u in zip(poses, readings):
        s = ms.sample(u)
        M = s.pose("platform")
        assert np.abs(M.translation - pose[:3]).max() < 1e-12
        assert np.abs(M.rotation - rotation_matrices(pose[3:], GEOMETRY.euler)).max() < 1e-12
        np.testing.assert_allclose(s.q[roll_q], KIN.nut_rotation(pose), atol=1e-12)
        np.testing.assert_allclose(robot.loops.actuated_values(s.q), u, atol=1e-14)
        miss.append(np.linalg.norm(plain.sample(u).pose("platform").translation - pose[:3]))
    assert 1e-5 < max(miss) < 2e-3     # tenths of a millimetre, as the spec's fixture


def test_parameter_jacobian_through_screw_rows_matches_finite_differences(robot):
    """Every kind: Hooke centres, encoder zeros (through the screw row), leads, Hooke axes."""
    _, readings = workspace(3, np.random.default_rng(2))
    params = floating_nut_parameters(robot, hooke_axes=True)
    rng = np.random.default_rng(3)
    for p in params:                      # away from the nominal point, so no term vanishes by symmetry
        if p.vary:
            p.value += rng.normal(0, 2e-5 if p.name.endswith(".lead") else 5e-4)
    problem = tracker_problem(robot, params, readings)
    assert len(params.free_names) == 6 * (3 + 3 + 1 + 1 + 3 + 3)
    assert_problem_jacobian(problem)


def test_frame_jacobians_through_screw_rows_match_finite_differences(robot):
    """Readings (through the screw rows) and leads, at one sample, with robocal.testing's own check."""
    _, readings = workspace(1, np.random.default_rng(4))
    params = floating_nut_parameters(robot, base_anchors=False, platform_anchors=False)
    assert_frame_jacobians(robot, params, robot.loops.actuated, readings[0], "platform")


def test_calibration_recovers_centres_zeros_and_leads(robot):
    rng = np.random.default_rng(5)
    truth = perturbed_truth(robot, rng)
    _, readings = workspace(30, rng)
    problem = tracker_problem(robot, floating_nut_parameters(robot), readings)
    simulate_measurements(problem, truth, rng)
    result = assert_calibration_recovers(problem, truth)
    assert result.selection.rank == 48 and not result.unidentifiable
    lead_err = max(abs(problem.params[f"leg{i}_screw.lead"].value - truth[f"leg{i}_screw.lead"].value)
                   for i in range(1, 7))
    assert lead_err < 5e-6                 # a 20 um lead error is found to a few um


def joint_position_errors(params, truth):
    """Largest 3D error (m) of the base and platform Hooke centres."""
    names = [f"leg{i}_hooke_base_1" for i in range(1, 7)] + [f"leg{i}_closure.link2" for i in range(1, 7)]
    return max(np.linalg.norm([params[f"{n}.{c}"].value - truth[f"{n}.{c}"].value for c in ("tx", "ty", "tz")])
               for n in names)


def prediction_errors(model_robot, params, robot, truth, readings):
    """Platform position error (m) of a fitted model against the true (compensated) machine at new readings."""
    fitted = ModelState(model_robot, params, robot.loops.actuated)
    real = ModelState(robot, truth, robot.loops.actuated)
    return np.array([np.linalg.norm(fitted.sample(u).pose("platform").translation
                                    - real.sample(u).pose("platform").translation) for u in readings])


def test_fitting_without_compensation_pushes_the_nut_roll_into_the_joint_positions(robot):
    """Spec §7.6: a 6-UPS fit absorbs the pose-dependent additional length (here up to 0.6 mm) into the
    Hooke centres and the encoder zeros, and predicts new poses worse by about as much."""
    rng = np.random.default_rng(6)
    truth = perturbed_truth(robot, rng, leads=False)          # leads as designed: only the roll differs
    poses, readings = workspace(40, rng, reach=0.15, tilt_deg=15.0)
    assert 4e-4 < np.abs(KIN.additional_lengths(poses)).max() < 8e-4
    compensated = tracker_problem(robot, floating_nut_parameters(robot, leads=False), readings)
    simulate_measurements(compensated, truth, rng)
    plain = uncompensated_robot(robot)
    uncompensated = tracker_problem(plain, floating_nut_parameters(plain, leads=False), readings)
    uncompensated.residuals[0].set_measurements(compensated.residuals[0].measurements.copy())
    ok, bad = calibrate(compensated), calibrate(uncompensated)
    assert ok.success and bad.success
    rms = {k: np.sqrt(np.mean(p.evaluate().raw.reshape(-1, 6)[:, :3] ** 2))
           for k, p in (("ok", compensated), ("bad", uncompensated))}
    assert rms["ok"] < 1.5 * SIGMA[0] and rms["bad"] > 5 * SIGMA[0]
    # the joint positions move by millimetres along the poorly conditioned strut directions
    err_ok, err_bad = (joint_position_errors(p.params, truth) for p in (compensated, uncompensated))
    assert err_bad > 1e-3 and err_bad > 5 * err_ok
    # and the model predicts new poses worse (the compensated one to the tracker's noise level)
    new = workspace(20, rng, reach=0.15, tilt_deg=15.0)[1]
    worst_ok = prediction_errors(robot, compensated.params, robot, truth, new).max()
    worst_bad = prediction_errors(plain, uncompensated.params, robot, truth, new).max()
    assert worst_ok < 3 * SIGMA[0] and worst_bad > 5e-5


def test_choose_thread_hands_finds_a_wrongly_mounted_screw(robot):
    rng = np.random.default_rng(7)
    truth = perturbed_truth(robot, rng)
    truth["leg3_screw.hand"].value = -truth["leg3_screw.hand"].value
    _, readings = workspace(25, rng, reach=0.1, tilt_deg=12.0)
    problem = tracker_problem(robot, floating_nut_parameters(robot), readings)
    simulate_measurements(problem, truth, rng)
    result, hands = choose_thread_hands(problem, legs=(2, 3))
    assert hands["leg3_screw"] == -1 and hands["leg2_screw"] == 1
    assert problem.params["leg3_screw.hand"].value == -1
    assert np.sqrt(np.mean(problem.evaluate().raw.reshape(-1, 6)[:, :3] ** 2)) < 1.5 * SIGMA[0]


def test_calibrated_urdf_reloads_to_the_same_machine(robot, tmp_path):
    """Anchors go into <loop_joint>, leads into <screw_transmission>, zeros of driven joints scaled by L/L0."""
    rng = np.random.default_rng(8)
    params = perturbed_truth(robot, rng)
    path = tmp_path / "calibrated.urdf"
    path.write_bytes(calibrated_urdf(robot, params))
    again = robocal.load_urdf(path)
    lead = {r.name: r.lead for r in again.loops.relations}
    assert lead["leg2_screw"] == pytest.approx(params["leg2_screw.lead"].value, rel=1e-15)
    assert {r.nominal_lead for r in again.loops.relations} == {0.01}
    ms, ms2 = ModelState(robot, params, robot.loops.actuated), ModelState(again, ParameterSet(), again.loops.actuated)
    for u in workspace(5, rng)[1]:
        a, b = ms.sample(u).pose("platform"), ms2.sample(u).pose("platform")
        assert np.abs(pin.log6(a.actInv(b)).vector).max() < 1e-12


@pytest.mark.parametrize("change, message", [
    (lambda ps: ps.add(Parameter("leg9_screw.lead", "transmission", "leg9_screw")),
     "no joint relation 'leg9_screw'"),
    (lambda ps: setattr(ps["leg1_screw.hand"], "vary", True), "discrete"),
], ids=["unknown_relation", "hand_varied"])
def test_bad_transmission_parameters_are_named(robot, change, message):
    params = floating_nut_parameters(robot)
    change(params)
    _, readings = workspace(2, np.random.default_rng(9))
    with pytest.raises(ValueError, match=message):
        tracker_problem(robot, params, readings).evaluate()


def test_transmission_parameter_on_a_serial_robot_is_refused():
    ur5 = robocal.load_example("ur5")
    params = ParameterSet([Parameter("x.lead", "transmission", "x")])
    with pytest.raises(ValueError, match="joint relations"):
        ModelState(ur5, params, [j for j in ur5.model.names[1:]])


@pytest.mark.parametrize("old, new, field", [
    ('sigma="1"', 'sigma="2"', "sigma"),
    ('roll_joint="leg1_nut_roll"', 'roll_joint="leg1_nut"', "roll_joint"),
    ('<actuated joints="leg1_stroke ', '<actuated joints="', "actuated"),
], ids=["bad_sigma", "unknown_roll_joint", "driven_not_actuated"])
def test_bad_screw_transmission_elements_name_file_and_field(tmp_path, old, new, field):
    text = URDF.read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "bad.urdf"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(InputError) as info:
        robocal.load_urdf(path)
    assert info.value.field == field and "bad.urdf" in str(info.value)
