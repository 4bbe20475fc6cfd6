"""TIAGo motion-capture study: the published reference figures reproduce, and the study's pieces work.

Published (FIGAROH, data README): norm RMSE of BL in mm, training / validation: registration 3.37 / 4.87,
joint_offset 2.88 / 4.23; joint_offset by posture group 3.31 / 4.47 / 6.53, per axis 2.37 / 2.59 / 2.35.
The figures are printed to 0.01 mm; the issue asks for agreement within 0.1 mm.
"""
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from robocal.estimation.calibrate import calibrate
from robocal.estimation.cross_validation import posture_groups
from robocal.workflows.evaluate import setup_for_data
from robocal.estimation.prediction_errors import term_errors

HERE = Path(__file__).parents[1] / "examples" / "tiago_mocap"
VALIDATION = HERE / "data" / "qualisys_2021-11-26_static_postures.csv"
TOL_MM = 0.1


def _fit_and_score(config, parameters=None):
    train = setup_for_data(HERE / config, parameters=parameters)
    result = calibrate(train.problem, train.options)
    val = setup_for_data(HERE / config, VALIDATION, parameters)
    block = train.problem.residuals[0].name
    return result, train, val, term_errors(train.problem)[block], term_errors(val.problem, train.problem.params)[block]


@pytest.mark.parametrize("config, n_params, published", [("registration_bl.yaml", 9, (3.37, 4.87)),
                                                        ("offsets_bl.yaml", 14, (2.88, 4.23))])
def test_reference_models_reproduce_the_published_rmse(config, n_params, published):
    result, _, _, tr, va = _fit_and_score(config)
    assert result.success and len(result.params.free_names) == n_params
    assert abs(tr.point_stats().rmse_norm - published[0]) < TOL_MM
    assert abs(va.point_stats().rmse_norm - published[1]) < TOL_MM


def test_joint_offset_validation_per_axis_and_posture_groups_reproduce():
    _, train, val, _, va = _fit_and_score("offsets_bl.yaml")
    np.testing.assert_allclose(va.point_stats().rmse_axes, [2.37, 2.59, 2.35], atol=TOL_MM)
    g = posture_groups(train.problem.values, val.problem.values)
    assert np.bincount(g).tolist() == [37, 16, 9]          # data README: 37 repeated, 16 new, 9 out of range
    got = [va.point_stats(0, g == k).rmse_norm for k in range(3)]
    np.testing.assert_allclose(got, [3.31, 4.47, 6.53], atol=TOL_MM)


def test_hand_pose_model_with_compliance_determines_the_gravity_loaded_joints():
    result, _, _, tr, va = _fit_and_score("hand_full_compliance.yaml")
    assert result.solve.success
    # not estimable from this data (data README): torso and arm_1 offsets, arm_7 roll
    assert {"torso_lift_joint.offset", "arm_1_joint.offset", "arm_7_joint.offset"} <= set(result.unidentifiable)
    # arm_1 turns about the vertical: no gravity torque, so no compliance to see
    assert "arm_1_joint.compliance" in result.unidentifiable
    c6 = result.params["arm_6_joint.compliance"]
    assert c6.value > 5 * c6.stderr                              # clearly non-zero at the wrist
    # the same training data fit better than the reference's joint_offset level (2.88 mm) by far more than
    # the 0.2 mm point noise, and the four-point hand model predicts the other day better than it (4.23 mm)
    assert tr.point_stats("BL").rmse_norm < 2.88 - 1.0
    assert va.point_stats("BL").rmse_norm < 4.23 - 0.5


def _study():
    spec = importlib.util.spec_from_file_location("run_study", HERE / "run_study.py")
    study = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = study
    spec.loader.exec_module(study)
    return study


def test_study_chooses_by_cross_validation_on_training_only():
    study = _study()
    fits = [study.fit(*m) for m in study.CANDIDATES[:1]] + [study.fit(*study.REFERENCE[1])]
    for f in fits:
        study.leave_one_out(f)
        assert f.validation is None
        assert f.loo.n == 37 and f.loo.rmse_norm > f.train.rmse_norm     # held out predicts worse than it fits
    assert study.choose(fits) is min(fits, key=lambda f: f.loo.rmse_norm)
    lines = study.table(fits)
    assert all("not scored on validation" in line for line in lines[2:])


CHOSEN = "hand, full + compliance + backlash + tilt (torso, arm_1), prior 2 mm / 10 mrad"
# Our own figures (run_study.py output, printed to 0.01 mm). The computation is deterministic; only rounding
# across platforms can move it, far below 0.01 mm, so 0.02 mm covers the printing and nothing more.
OWN_TOL_MM = 0.02


def test_tilt_model_is_chosen_by_leave_one_out_and_its_validation_figures_hold(tmp_path):
    """The chosen model, its nearest rival in LOO (1.80 mm) and revision 2's choice (1.87 mm); all twenty
    candidates are cross-validated by run_study.py only (about five minutes)."""
    study = _study()
    rivals = [m for m in study.CANDIDATES if m[0] in (
        CHOSEN, "hand, full + compliance + backlash + tilt (torso, arm_1), prior 1 mm / 5 mrad",
        "hand, full + compliance + backlash, prior 2 mm / 10 mrad")]
    fits = [study.fit(*m) for m in rivals]
    for f in fits:
        study.leave_one_out(f)
    best = study.choose(fits)
    assert best.label == CHOSEN
    np.testing.assert_allclose(sorted(f.loo.rmse_norm for f in fits), [1.70, 1.80, 1.87], atol=OWN_TOL_MM)
    study.validate(best)                                          # once, for the chosen model only
    v = best.validation
    np.testing.assert_allclose([*v.rmse_axes, v.rmse_norm], [1.35, 1.00, 1.67, 2.37], atol=OWN_TOL_MM)
    np.testing.assert_allclose([best.groups[g].rmse_norm for g in study.GROUPS], [1.77, 1.80, 4.48],
                               atol=OWN_TOL_MM)
    assert v.rmse_norm < 2.5                                      # the validation target
    # the out-of-range group, posture by posture: the arm_1-only excursions (up to 0.26 rad) are predicted
    # at the in-range level; rows 0, 4 and 5 take the wrist 0.26-1.18 rad past its training range
    rows = {row: (err, dict(joints)) for row, err, joints in best.outside}
    assert sorted(rows) == [0, 2, 3, 4, 5, 58, 59, 60, 61]
    np.testing.assert_allclose([rows[k][0] for k in sorted(rows)], [8.73, 1.03, 1.68, 7.97, 5.04, 2.53, 1.32,
                                                                   0.73, 1.64], atol=OWN_TOL_MM)
    assert np.sqrt(np.mean([e ** 2 for e, _ in rows.values()])) == pytest.approx(best.groups["out of range"].rmse_norm)
    assert rows[4][1] == pytest.approx({"arm_6_joint": -1.05, "arm_7_joint": 1.18}, abs=0.005)
    study.edge_cv(best)                                           # training range ends held out: 2.26 mm
    assert best.edge.n == 24 and abs(best.edge.rmse_norm - 2.26) < OWN_TOL_MM
    reference = study.fit(*study.REFERENCE[1])                    # the docs' figures: joint_offset vs chosen
    study.validate(reference)
    for png in study.write_plots(reference, best, tmp_path):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    r = best.result
    # the wrist play is clearly determined: arm_5 and arm_6 about -6 mrad (link lags the reading)
    for j in ("arm_5_joint", "arm_6_joint"):
        b = r.params[f"{j}.backlash"]
        assert b.value < -5 * b.stderr
    assert {"torso_lift_joint.offset", "arm_1_joint.offset", "arm_7_joint.offset"} <= set(r.unidentifiable)
    t = r.params["arm_1_joint.tilt"]                              # the arm_1 tilt is determined (5 s.e.)
    assert t.value > 3 * t.stderr
