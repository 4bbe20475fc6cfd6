"""Sessions: one robot, a measurement frame re-registered per session (robocal.estimation.sessions)."""
import numpy as np
import pytest

from robocal import Problem, calibrate, load_example, robot_parameters
from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from robocal.estimation.sessions import Sessions
from robocal.residuals import PointResidual, RigidPointsResidual
from robocal.testing import assert_problem_jacobian

SIGMA = 5e-5          # m, tracker noise per coordinate


def two_session_problem(n_per_session=30, seed=0, blocks=("point",)):
    robot = load_example("ur5")
    joints = robot.joint_names
    rng = np.random.default_rng(seed)
    n = 2 * n_per_session
    values = random_configurations(robot, joints, n, rng)
    params = robot_parameters(robot, joints, "full", base=True)
    residuals = []
    if "point" in blocks:
        residuals.append(PointResidual("marker", "tool0", np.arange(n), np.zeros((n, 3)), point=(0.01, 0.02, 0.05),
                                       point_unknown=True, sigma=SIGMA))
    if "cluster" in blocks:
        pts = np.array([[0.03, 0.0, 0.04], [0.0, 0.03, 0.04], [-0.03, 0.0, 0.04]])
        residuals.append(RigidPointsResidual("cluster", "tool0", np.arange(n), np.zeros((n, 9)), pts, sigma=SIGMA))
    sessions = Sessions(("day1", "day2"), np.repeat([0, 1], n_per_session))
    return Problem(robot, params, joints, values, residuals, sessions=sessions), rng


def test_session_parameters_and_their_jacobian_match_finite_differences():
    problem, rng = two_session_problem(6, blocks=("point", "cluster"))
    names = [p.name for p in problem.params if p.kind == "session_frame"]
    assert names == [f"base@day2.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz")]
    for name, v in zip(names, (0.02, -0.01, 0.005, 0.01, -0.02, 0.015)):
        problem.params[name].value = v
    problem.params["base.tx"].value, problem.params["base.rz"].value = 0.1, 0.3
    # both paths: the point block is batched, the rigid cluster goes sample by sample
    assert_problem_jacobian(problem)


def test_a_shared_robot_and_a_frame_per_session_are_recovered():
    """Synthetic truth: day2's tracker moved 20 mm / 10 mrad; robot errors of 2 mm / 0.2 deg shared."""
    problem, rng = two_session_problem(30)
    truth = perturb(problem.params, rng, 2e-3, np.radians(0.2))
    for name, v in zip([f"base@day2.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz")],
                       (0.02, -0.01, 0.005, 0.01, -0.005, 0.008)):
        truth[name].value = v
    simulate_measurements(problem, truth, rng)
    result = calibrate(problem)
    assert result.success, result.status
    for p in problem.params:
        if p.kind == "session_frame":
            # within 4 standard errors (the noise's prediction; 6 components)
            assert abs(p.value - truth[p.name].value) < 4 * p.stderr, (p.name, p.value, truth[p.name].value)
    # without the session frame the shared model cannot explain both days
    single, _ = two_session_problem(30)
    single.sessions = None
    for res, src in zip(single.residuals, problem.residuals):
        res.measurements = src.measurements.copy()
    bad = calibrate(single)
    assert bad.after[0].rms["mm"] > 10 * result.after[0].rms["mm"]


def test_sessions_must_name_every_sample():
    robot = load_example("ur5")
    with pytest.raises(ValueError, match="sessions name 3 samples"):
        Problem(robot, robot_parameters(robot, robot.joint_names, "offsets"), robot.joint_names, np.zeros((4, 6)),
                [], sessions=Sessions(("a", "b"), np.array([0, 0, 1])))


def tiago_sessions_config(tmp_path, **data):
    from pathlib import Path
    here = Path(__file__).resolve().parents[1] / "examples" / "tiago_mocap" / "data"
    import yaml
    cfg = {"robot": {"urdf": str(here / "tiago_48_schunk.urdf")},
           "data": {"joints": ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)], **data},
           "parameters": {"preset": "offsets", "base": True},
           "measurements": [{"type": "point", "name": "BL", "frame": "wrist_ft_tool_link", "point_unknown": True,
                             "columns": ["x1", "y1", "z1"], "sigma": 0.0005}],
           "output": {"dir": str(tmp_path / "out"), "report": False}}
    path = tmp_path / "sessions.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path, here


def test_a_config_with_two_sessions_fits_them_jointly_and_holds_each_out(tmp_path):
    from robocal.workflows import load_config
    from robocal.workflows.cv import make_folds, run_cv
    here = tiago_sessions_config(tmp_path)[1]
    path, _ = tiago_sessions_config(tmp_path, sessions=[
        {"name": "nov30", "csv": str(here / "qualisys_2021-11-30_static_postures.csv")},
        {"name": "nov26", "csv": str(here / "qualisys_2021-11-26_static_postures.csv")}])
    setup = load_config(path)
    assert setup.problem.sessions.names == ("nov30", "nov26")
    assert np.bincount(setup.problem.sessions.of_sample).tolist() == [37, 62]
    folds, label = make_folds(setup)
    assert label.startswith("leave-one-session-out") and [len(f) for f in folds] == [37, 62]
    table, _, _ = run_cv(path)
    # the held-out session's frame is registered on its own data before it is scored
    assert table.folds[0]["registered"] == [f"base.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz")]
    assert table.folds[1]["registered"][0] == "base@nov26.tx"
    result = calibrate(setup.problem)
    assert [s["session"] for s in result.sessions] == ["nov30", "nov26"]
    assert "frame_correction" in result.sessions[1] and "frame_correction" not in result.sessions[0]


def test_a_session_column_splits_one_csv(tmp_path):
    import csv
    from robocal.workflows import load_config
    here = tiago_sessions_config(tmp_path)[1]
    rows = list(csv.DictReader(open(here / "qualisys_2021-11-30_static_postures.csv")))
    with open(tmp_path / "both.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) + ["day"])
        w.writeheader()
        for k, r in enumerate(rows):
            w.writerow({**r, "day": "a" if k < 20 else "b"})
    path, _ = tiago_sessions_config(tmp_path, csv=str(tmp_path / "both.csv"), session_column="day")
    sessions = load_config(path).problem.sessions
    assert sessions.names == ("a", "b") and np.bincount(sessions.of_sample).tolist() == [20, 17]


def test_posture_folds_keep_repeats_together():
    from robocal.estimation.cross_validation import posture_folds
    values = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.005], [2.0, 1.0], [1.0, 0.002]])
    folds = posture_folds(values, 5)
    assert [f.tolist() for f in folds] == [[0, 2], [1, 4], [3]]
