"""Issue 32, must-hold (a): two sessions with different tracker placements and an unmodelled joint compliance.
`robocal select` (the workflow) picks a model containing the compliance, and the joint fit of both sessions
recovers the truth within 3 standard errors."""
import csv

import numpy as np
import yaml

from robocal import Problem, load_example, robot_parameters
from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from robocal.estimation.sessions import Sessions
from robocal.residuals import PointResidual
from robocal.workflows import load_config, select_model
from robocal.workflows.calibrate import run_calibration

JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint"]
SIGMA = 5e-5           # m, tracker noise per coordinate
N = 40                 # postures per session
TRACKER = [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0), (0.25, -0.1, 0.05, 0.03, -0.02, 0.15)]   # day2's tracker moved


def write_sessions(folder, rng):
    """Two CSVs of one UR5 with compliance at two joints, day2 seen from a moved tracker; returns the truth."""
    robot = load_example("ur5")
    values = random_configurations(robot, JOINTS, 2 * N, rng)
    params = robot_parameters(robot, JOINTS, "offsets", compliance=["shoulder_lift_joint", "elbow_joint"],
                              base=True)
    marker = PointResidual("marker", "tool0", np.arange(2 * N), np.zeros((2 * N, 3)), point=(0.02, 0.01, 0.05),
                           sigma=SIGMA)
    sessions = Sessions(("day1", "day2"), np.repeat([0, 1], N))
    problem = Problem(robot, params, JOINTS, values, [marker], sessions=sessions)
    truth = perturb(problem.params, rng, 1e-3, 2e-3, patterns=["*.offset"])
    truth["shoulder_lift_joint.compliance"].value = 4e-5      # rad / N m: ~2 mrad of sag at ~50 N m
    truth["elbow_joint.compliance"].value = 6e-5
    for c, v in zip(("tx", "ty", "tz", "rx", "ry", "rz"), TRACKER[1]):
        truth[f"base@day2.{c}"].value = v
    simulate_measurements(problem, truth, rng)
    for s, name in enumerate(("day1", "day2")):
        with open(folder / f"{name}.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(JOINTS + ["x", "y", "z"])
            for i in sessions.samples_of(s):
                w.writerow([repr(float(v)) for v in values[i]] + [repr(float(v)) for v in marker.measurements[i]])
    return truth


def test_select_picks_the_compliance_and_the_joint_fit_recovers_the_truth(tmp_path):
    truth = write_sessions(tmp_path, np.random.default_rng(7))
    config = {"robot": {"example": "ur5"},
              "data": {"sessions": [{"name": "day1", "csv": "day1.csv"}, {"name": "day2", "csv": "day2.csv"}],
                       "joints": JOINTS},
              "parameters": {"preset": "offsets", "base": True, "compliance": ["shoulder_lift_joint", "elbow_joint"]},
              "measurements": [{"type": "point", "name": "marker", "frame": "tool0", "point": [0.02, 0.01, 0.05],
                                "columns": ["x", "y", "z"], "sigma": SIGMA}],
              "output": {"dir": "out", "report": False}}
    path = tmp_path / "select.yaml"
    path.write_text(yaml.safe_dump(config))
    selection = select_model(path)
    assert selection.folds.startswith("leave-one-session-out")
    assert "compliance" in selection.rungs[selection.chosen].name, selection.table()
    run = run_calibration(load_config(path))
    params = run.result.params
    for name in ("shoulder_lift_joint.compliance", "elbow_joint.compliance",
                 *[f"base@day2.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz")]):
        p = params[name]
        assert abs(p.value - truth[name].value) < 3 * p.stderr, (name, p.value, truth[name].value, p.stderr)
