"""ISO 9283 figures against hand computations of the standard's formulas, and on a synthetic robot
with a known bias and known noise."""
import math

import numpy as np
import pinocchio as pin
import pytest

from robocal import load_example
from robocal.errors import InputError
from robocal.estimation.iso9283 import (distance_characteristics, iso9283_figures, model_attained, pose6,
                             pose_characteristics, summary)
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters
from robocal.design.simulate import perturb, random_configurations


def _mean(v):
    return sum(v) / len(v)


def _s(v):
    """The standard's S: sqrt(sum (v - mean)^2 / (n - 1)), written out."""
    m = _mean(v)
    return math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1))


def _hand_pose(c, visits):
    """AP / RP of ISO 9283 7.2.1 and 7.2.2 from lists of numbers."""
    n = len(visits)
    bar = [sum(v[k] for v in visits) / n for k in range(6)]
    ap = [bar[k] - c[k] for k in range(6)]
    l = [math.sqrt(sum((v[k] - bar[k]) ** 2 for k in range(3))) for v in visits]
    return {"AP": math.sqrt(ap[0] ** 2 + ap[1] ** 2 + ap[2] ** 2), "AP6": ap,
            "RP": _mean(l) + 3 * _s(l), "l_bar": _mean(l), "S_l": _s(l),
            "RPabc": [3 * _s([v[k] for v in visits]) for k in (3, 4, 5)]}


def _hand_distance(c1, c2, v1, v2):
    """AD / RD of ISO 9283 7.5 from lists of numbers."""
    D = [math.sqrt(sum((a[k] - b[k]) ** 2 for k in range(3))) for a, b in zip(v1, v2)]
    Dc = math.sqrt(sum((c1[k] - c2[k]) ** 2 for k in range(3)))
    ad6 = [_mean([a[k] - b[k] for a, b in zip(v1, v2)]) - (c1[k] - c2[k]) for k in range(6)]
    rd6 = [3 * _s([a[k] - b[k] for a, b in zip(v1, v2)]) for k in range(6)]
    return {"AD": _mean(D) - Dc, "RD": 3 * _s(D), "AD6": ad6, "RD6": rd6}


def test_tiny_explicit_pose_array_matches_the_formulas_worked_by_hand():
    c = [1.0, 2.0, 3.0, 0.1, 0.2, 0.3]
    visits = [[1.001, 2.000, 3.002, 0.101, 0.2, 0.3],
              [1.003, 2.002, 3.000, 0.103, 0.2, 0.299],
              [1.002, 2.001, 3.001, 0.102, 0.201, 0.301]]
    f = pose_characteristics(c, visits, "P1")
    # Worked by hand: barycentre (1.002, 2.001, 3.001); AP_x = 0.002, AP_y = AP_z = 0.001,
    # AP = sqrt(6) mm; l_1 = l_2 = sqrt(3) mm, l_3 = 0, l_bar = 2 sqrt(3)/3 mm, S_l = sqrt(3)/sqrt(3)
    # = 1 mm (deviations sqrt3/3, sqrt3/3, -2sqrt3/3 -> sum of squares 2, / 2 = 1); RP = 2/sqrt3 + 3 mm;
    # a: 0.101, 0.103, 0.102 -> AP_a = 0.002, S_a = 0.001, RP_a = 0.003.
    assert f.AP == pytest.approx(math.sqrt(6) * 1e-3, abs=1e-12)
    np.testing.assert_allclose(f.AP_xyz, [2e-3, 1e-3, 1e-3], atol=1e-12)
    assert f.AP_abc[0] == pytest.approx(2e-3, abs=1e-12)
    assert f.l_bar == pytest.approx(2 / math.sqrt(3) * 1e-3, abs=1e-12)
    assert f.S_l == pytest.approx(1e-3, abs=1e-12)
    assert f.RP == pytest.approx((2 / math.sqrt(3) + 3) * 1e-3, abs=1e-12)
    assert f.RP_abc[0] == pytest.approx(3e-3, abs=1e-12)
    hand = _hand_pose(c, visits)
    np.testing.assert_allclose(np.r_[f.AP_xyz, f.AP_abc], hand["AP6"], atol=1e-12)
    np.testing.assert_allclose(f.RP_abc, hand["RPabc"], atol=1e-12)


def test_tiny_explicit_distance_array_matches_the_formulas_worked_by_hand():
    c1, c2 = [0, 0, 0, 0, 0, 0], [0.3, 0.4, 0, 0, 0, 0.5]       # D_c = 0.5 m
    v1 = [[0.001, 0, 0, 0, 0, 0], [0.0, 0, 0, 0, 0, 0], [-0.001, 0, 0, 0, 0, 0]]
    v2 = [[0.3, 0.4, 0, 0, 0, 0.501], [0.3, 0.4, 0, 0, 0, 0.5], [0.3, 0.4, 0, 0, 0, 0.502]]
    d = distance_characteristics(c1, c2, v1, v2)
    hand = _hand_distance(c1, c2, v1, v2)
    assert d.AD == pytest.approx(hand["AD"], abs=1e-12)
    assert d.RD == pytest.approx(hand["RD"], abs=1e-12)
    np.testing.assert_allclose(d.AD_xyzabc, hand["AD6"], atol=1e-12)
    np.testing.assert_allclose(d.RD_xyzabc, hand["RD6"], atol=1e-12)
    # by hand: D_c - c: -0.001, 0, +0.001 along x -> AD_c = -(0.001+0+0.002)/3 = -0.001 rad
    assert d.AD_xyzabc[5] == pytest.approx(-0.001, abs=1e-12)


def test_angles_straddling_pi_are_averaged_as_differences():
    c = [0, 0, 0, 0, 0, np.pi - 0.001]
    visits = [[0, 0, 0, 0, 0, np.pi - 0.002], [0, 0, 0, 0, 0, -np.pi + 0.001]]   # -0.001 and +0.002 rad off
    f = pose_characteristics(c, visits)
    assert f.AP_abc[2] == pytest.approx(0.0005, abs=1e-12)
    assert f.RP_abc[2] == pytest.approx(3 * 0.003 / math.sqrt(2), abs=1e-12)


def _rpy(R):
    """Roll-pitch-yaw of R = Rz(c) Ry(b) Rx(a), written independently of pinocchio."""
    return [math.atan2(R[2, 1], R[2, 2]), math.atan2(-R[2, 0], math.hypot(R[2, 1], R[2, 2])),
            math.atan2(R[1, 0], R[0, 0])]


def _synthetic_ur5(seed=11, n_poses=4, visits=10, sigma_q=1e-4, sigma_m=2e-5):
    """Nominal controller, perturbed true robot (bias), joint repeatability and tracker noise."""
    rng = np.random.default_rng(seed)
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full")
    truth = perturb(params, rng, 2e-3, np.radians(0.2))
    nominal, true = ModelState(robot, params, joints), ModelState(robot, truth, joints)
    qc = random_configurations(robot, joints, n_poses, rng, span=0.8)
    ids, q_rows, P, meas = [], [], [], []
    for cycle in range(visits):
        for k in range(n_poses):
            q = qc[k] + rng.normal(0, sigma_q, len(joints))
            M = true.sample(q).pose("tool0")
            noisy = pin.SE3(pin.exp3(rng.normal(0, sigma_m, 3)) @ M.rotation,
                            M.translation + rng.normal(0, sigma_m, 3))
            ids.append(f"P{k + 1}")
            q_rows.append(q)
            P.append(nominal.sample(qc[k]).pose("tool0"))
            meas.append(noisy)
    return dict(robot=robot, joints=joints, params=params, truth=truth, nominal=nominal, true=true, qc=qc,
                ids=ids, P=P, meas=meas, sigma_q=sigma_q, sigma_m=sigma_m, visits=visits)


@pytest.fixture(scope="module")
def ur5_case():
    return _synthetic_ur5()


def test_synthetic_robot_figures_equal_the_hand_computation(ur5_case):
    c = ur5_case
    fig = iso9283_figures(c["ids"], [pose6(P) for P in c["P"]], [pose6(M) for M in c["meas"]])
    assert [p.pose_id for p in fig.poses] == ["P1", "P2", "P3", "P4"]
    assert [d.pose_ids for d in fig.distances] == [("P1", "P2"), ("P2", "P3"), ("P3", "P4")]
    rows = {}
    for i, pid in enumerate(c["ids"]):
        M = c["meas"][i]
        rows.setdefault(pid, []).append(list(M.translation) + _rpy(M.rotation))
    cmd = {pid: list(c["P"][c["ids"].index(pid)].translation) + _rpy(c["P"][c["ids"].index(pid)].rotation)
           for pid in rows}
    for f in fig.poses:
        hand = _hand_pose(cmd[f.pose_id], rows[f.pose_id])
        assert abs(f.AP - hand["AP"]) < 1e-9
        assert abs(f.RP - hand["RP"]) < 1e-9
        assert np.abs(np.r_[f.AP_xyz, f.AP_abc] - hand["AP6"]).max() < 1e-9
        assert np.abs(f.RP_abc - hand["RPabc"]).max() < 1e-9
    for d in fig.distances:
        a, b = d.pose_ids
        hand = _hand_distance(cmd[a], cmd[b], rows[a], rows[b])
        assert abs(d.AD - hand["AD"]) < 1e-9 and abs(d.RD - hand["RD"]) < 1e-9
        assert np.abs(d.AD_xyzabc - hand["AD6"]).max() < 1e-9
        assert np.abs(d.RD_xyzabc - hand["RD6"]).max() < 1e-9


def _visit_sigma(c, k):
    """Per-axis standard deviation of a visit's position around true(q_c) for pose k.

    Visit j lands at true(q_c) + Jp dq_j + noise, so per axis s = sqrt(sigma_q^2 sum_i Jp[axis, i]^2
    + sigma_m^2); the barycentre of n visits has s / sqrt(n).
    """
    s_true = c["true"].sample(c["qc"][k])
    Jp = s_true.pose("tool0").rotation @ s_true.frame_joint_jacobian("tool0")[:3]
    return np.sqrt(c["sigma_q"] ** 2 * np.sum(Jp ** 2, axis=1) + c["sigma_m"] ** 2)


def test_synthetic_robot_accuracy_is_the_known_bias_within_the_noise(ur5_case):
    c = ur5_case
    fig = iso9283_figures(c["ids"], [pose6(P) for P in c["P"]], [pose6(M) for M in c["meas"]])
    for k, f in enumerate(fig.poses):
        bias = (c["true"].sample(c["qc"][k]).pose("tool0").translation
                - c["nominal"].sample(c["qc"][k]).pose("tool0").translation)
        s = _visit_sigma(c, k)
        # 5 standard deviations of the barycentre: with 12 checks a false failure has probability ~1e-5
        assert np.all(np.abs(f.AP_xyz - bias) < 5 * s / np.sqrt(c["visits"]))
        assert np.linalg.norm(bias) > 10 * np.max(s)   # so the check above is about the bias, not noise


def test_calibrated_model_removes_the_bias_and_keeps_the_repeatability(ur5_case):
    c = ur5_case
    n = len(c["ids"])
    k_of = [int(pid[1:]) - 1 for pid in c["ids"]]
    cmd = [pose6(P) for P in c["P"]]
    nominal = iso9283_figures(c["ids"], cmd, [pose6(M) for M in c["meas"]], label="nominal")
    # The truth as the calibrated model: what remains is repeatability and tracker noise.
    at_cmd = [c["true"].sample(c["qc"][k]).pose("tool0") for k in k_of]
    calibrated = iso9283_figures(c["ids"], cmd, [pose6(M) for M in model_attained(c["P"], at_cmd, c["meas"])],
                                 label="calibrated")
    assert len(calibrated.poses) == 4 and n == 40
    for fn, fc in zip(nominal.poses, calibrated.poses):
        # a rigid transform of all visits of a pose leaves their distances to the barycentre unchanged
        assert abs(fn.RP - fc.RP) < 1e-12 and abs(fn.l_bar - fc.l_bar) < 1e-12
    for k, (fn, fc) in enumerate(zip(nominal.poses, calibrated.poses)):
        # What is left is the barycentre's noise, rotated by P_c true(q_c)^-1 (0.2 deg from identity):
        # each axis stays within 5 max(s) / sqrt(n), so the norm within sqrt(3) times that.
        s = _visit_sigma(c, k)
        assert fc.AP < np.sqrt(3) * 5 * s.max() / np.sqrt(c["visits"]) < fn.AP
    # with the nominal model the predicted attained poses are the measured ones
    same = model_attained(c["P"], c["P"], c["meas"])
    assert max(np.abs(pose6(a) - pose6(b)).max() for a, b in zip(same, c["meas"])) < 1e-12
    text = summary([nominal, calibrated])
    assert "mm" in text and "mrad" in text and "nominal" in text and "calibrated" in text


def test_bad_inputs_are_named():
    with pytest.raises(InputError, match="pose 'P9' is visited 1 time"):
        pose_characteristics(np.zeros(6), np.zeros((1, 6)), "P9")
    with pytest.raises(InputError, match="different commanded poses"):
        iso9283_figures(["A", "A"], [[0] * 6, [1e-3] + [0] * 5], np.zeros((2, 6)))
    with pytest.raises(InputError, match="names pose 'Z'"):
        iso9283_figures(["A", "A"], np.zeros((2, 6)), np.zeros((2, 6)), distance_pairs=[("A", "Z")])
    fig = iso9283_figures(["A", "A", "B", "B", "B"], np.zeros((5, 6)), np.ones((5, 6)) * 1e-3)
    assert fig.distances == [] and "cannot be paired" in fig.notes[0]
