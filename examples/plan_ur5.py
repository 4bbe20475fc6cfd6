"""Experiment design on a UR5 with a 6D laser-tracker probe: which 30 poses, and what accuracy to expect.

Run: OMP_NUM_THREADS=1 python examples/plan_ur5.py
The same plan from a YAML file: `robocal plan CONFIG` (see docs/experiment_design.md).
"""
import numpy as np

from robocal import load_example
from robocal.design import DesignMatrix, select_poses
from robocal.design import MeasurementVolume, filter_candidates, random_candidates
from robocal.model import ModelState
from robocal.model import ParameterSet, robot_parameters
from robocal.design import pose_jacobians, predict_parameters, predict_pose_accuracy
from robocal.estimation import Problem
from robocal.residuals import PoseResidual

robot = load_example("ur5")
joints = robot.joint_names
rng = np.random.default_rng(1)

# 1. Candidates: 1000 random readings within the limits; drop near-singular ones and those the tracker
#    (1.5 m in front of the robot, 0.5 m to 3 m range) cannot see.
proposed = random_candidates(robot, joints, 1000, rng)
tracker = MeasurementVolume(center=np.array([1.5, 0.0, 0.3]), max_range=3.0, min_range=0.5)
screen = filter_candidates(ModelState(robot, ParameterSet(), joints), proposed, "tool0", tracker)
candidates = proposed[screen.kept]
print(f"{len(candidates)} candidates kept; dropped: {screen.dropped}")

# 2. One problem over all candidates (measurements are predicted: there are no data yet), one Jacobian.
params = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True)
n = len(candidates)
tracker_poses = PoseResidual("tracker", "tool0", np.arange(n), np.tile([0, 0, 0, 0, 0, 0, 1.0], (n, 1)),
                             sigma=(5e-5, 5e-5))                      # 50 um, 50 urad
problem = Problem(robot, params, joints, candidates, [tracker_poses])
design = DesignMatrix.from_problem(problem)
print(f"{len(design.base_names)} identifiable parameters of {len(design.names)}")

# 3. Choose 30 poses and predict the tool accuracy over 200 validation configurations.
G = pose_jacobians(problem, "tool0", random_candidates(robot, joints, 200, rng))
print("\ncriterion  mean position [mm]  max position [mm]  mean orientation [mrad]")
for criterion in ("D", "E", "O1", "O4"):
    sel = select_poses(design, 30, criterion)
    acc = predict_pose_accuracy(predict_parameters(design, sel.chosen), G).summary()
    print(f"{criterion:>9}  {acc['mean_position_mm']:18.4f}  {acc['max_position_mm']:17.4f}  "
          f"{acc['mean_orientation_mrad']:23.4f}")
random_sets = [predict_pose_accuracy(predict_parameters(design, rng.choice(n, 30, replace=False)), G)
               .summary()["mean_position_mm"] for _ in range(100)]
print(f"   random  {np.median(random_sets):18.4f}  (median of 100 random sets of 30)")

# 4. Accuracy against the number of poses (D-optimal each time).
print("\nposes  mean position [mm]")
for count in (8, 15, 30, 60):
    sel = select_poses(design, count, "D")
    pp = predict_pose_accuracy(predict_parameters(design, sel.chosen), G)
    print(f"{count:5d}  {pp.summary()['mean_position_mm']:.4f}")

# 5. The chosen readings (rad) to send to the robot.
best = select_poses(design, 30, "D")
np.set_printoptions(precision=4, suppress=True)
print("\nfirst 5 of the 30 D-optimal poses [rad]:\n", candidates[best.labels[:5]])
