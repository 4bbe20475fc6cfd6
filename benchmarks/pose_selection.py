"""Pose selection on UR5 (6D tracker, full placement parameters): speed per criterion, predicted accuracy
against random pose sets, and prediction against Monte-Carlo synthetic-truth calibrations.

Run:  OMP_NUM_THREADS=1 python benchmarks/pose_selection.py [--candidates 1000] [--poses 30] [--trials 100]
          [--baseline-commit 215e72e]
Times are wall clock, one thread, one run (greedy start + exchange). The first table times the baseline
(robocal/design/criteria.py as of --baseline-commit, read with `git show` into a temporary module, so the
commit must be in this repository's history) against the current code on the same design, and checks that
both choose the same poses.
"""
from __future__ import annotations

import argparse
import contextlib
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from git_baseline import module_at_commit  # noqa: E402
from robocal import load_example  # noqa: E402
from robocal.estimation.calibrate import calibrate  # noqa: E402
from robocal.design import selection  # noqa: E402
from robocal.design.selection import DesignMatrix, select_poses  # noqa: E402
from robocal.design.candidates import random_candidates  # noqa: E402
from robocal.design.criteria import CRITERIA  # noqa: E402
from robocal.model.kinematics import ModelState  # noqa: E402
from robocal.model.parameters import robot_parameters  # noqa: E402
from robocal.design.prediction import pose_jacobians, position_weight, predict_parameters, predict_pose_accuracy  # noqa: E402
from robocal.estimation.problem import Problem  # noqa: E402
from robocal.residuals import PoseResidual  # noqa: E402
from robocal.design.simulate import perturb, simulate_measurements  # noqa: E402

SIGMA = (5e-5, 5e-5)


@contextlib.contextmanager
def criteria_module(module):
    """select_poses with `module` in place of robocal.design.criteria (selection.py calls it as `dc`)."""
    current = selection.dc
    selection.dc = module
    try:
        yield
    finally:
        selection.dc = current


def speed_table(design, n, W, baseline):
    """Baseline against current select_poses per criterion: times and whether the same poses are chosen."""
    print(f"\nselect_poses, {n} poses of {design.n_candidates} (greedy + exchange), one thread")
    print("criterion  baseline [s]  current [s]  speed-up  same poses  |value difference|")
    for c in CRITERIA:
        with criteria_module(baseline):
            t0 = time.perf_counter()
            old = select_poses(design, n, c, W=W)
            t_old = time.perf_counter() - t0
        t0 = time.perf_counter()
        new = select_poses(design, n, c, W=W)
        t_new = time.perf_counter() - t0
        same = "yes" if np.array_equal(old.chosen, new.chosen) else "NO"
        print(f"{c:>9}  {t_old:12.2f}  {t_new:11.2f}  {t_old / t_new:8.1f}  {same:>10}  {abs(old.value - new.value):18.1e}")


def ur5_problem(values):
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True)
    n = len(values)
    res = PoseResidual("tracker", "tool0", np.arange(n), np.tile([0, 0, 0, 0, 0, 0, 1.0], (n, 1)), sigma=SIGMA)
    return Problem(robot, params, joints, values, [res])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--candidates", type=int, default=1000)
    ap.add_argument("--poses", type=int, default=30)
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--baseline-commit", default="215e72e",
                    help="commit whose robocal/design/criteria.py is timed as the baseline ('' to skip)")
    a = ap.parse_args()
    robot = load_example("ur5")
    rng = np.random.default_rng(0)
    values = random_candidates(robot, robot.joint_names, a.candidates, rng)
    problem = ur5_problem(values)
    t0 = time.perf_counter()
    design = DesignMatrix.from_problem(problem)
    print(f"Jacobian of {a.candidates} candidates: {time.perf_counter() - t0:.2f} s; "
          f"{len(design.base_names)} identifiable parameters of {len(design.names)}")
    validation = random_candidates(robot, robot.joint_names, 300, rng)
    G = pose_jacobians(problem, "tool0", validation)
    W = position_weight(G)
    if a.baseline_commit:
        baseline = module_at_commit(a.baseline_commit, "robocal/design/criteria.py", "baseline_criteria")
        speed_table(design, a.poses, W, baseline)

    print(f"\n{a.poses} poses of {a.candidates}: predicted tool0 accuracy over 300 configurations (1 sigma)")
    print("criterion   time [s]  exchanges  mean pos [mm]  max pos [mm]  mean rot [mrad]  log det")
    chosen = {}
    for c in CRITERIA:
        t0 = time.perf_counter()
        sel = select_poses(design, a.poses, c, W=W)
        dt = time.perf_counter() - t0
        acc = predict_pose_accuracy(predict_parameters(design, sel.chosen), G).summary()
        chosen[c] = sel
        print(f"{c:>9}  {dt:9.2f}  {sel.exchanges:9d}  {acc['mean_position_mm']:13.4f}  {acc['max_position_mm']:12.4f}"
              f"  {acc['mean_orientation_mrad']:15.4f}  {sel.values['D']:7.2f}")
    rand = np.array([predict_pose_accuracy(predict_parameters(design, rng.choice(a.candidates, a.poses, replace=False)),
                                           G).mean_position for _ in range(100)]) * 1e3
    print(f"   random  (100 sets)  mean pos [mm]: median {np.median(rand):.4f}, best {rand.min():.4f}, "
          f"worst {rand.max():.4f}")

    # Monte Carlo: calibrate on the D-optimal poses, compare achieved and predicted RMS tool error.
    sel = chosen["D"]
    pred = predict_parameters(design, sel.chosen)
    predicted = predict_pose_accuracy(pred, G).rms_position
    ms_err = []
    t0 = time.perf_counter()
    for _ in range(a.trials):
        fit = ur5_problem(values[sel.labels].copy())
        truth = perturb(fit.params, rng)
        simulate_measurements(fit, truth, rng)
        calibrate(fit)
        est, true = (ModelState(fit.robot, p, fit.joint_names) for p in (fit.params, truth))
        e = np.array([est.sample(v).pose("tool0").translation - true.sample(v).pose("tool0").translation
                      for v in validation])
        ms_err.append(np.mean(np.sum(e ** 2, axis=1)))
    achieved = np.sqrt(np.mean(ms_err))
    print(f"\nMonte Carlo ({a.trials} calibrations, {time.perf_counter() - t0:.1f} s): RMS tool0 position error "
          f"achieved {achieved * 1e3:.4f} mm, predicted {predicted * 1e3:.4f} mm, ratio {achieved / predicted:.3f}")


if __name__ == "__main__":
    main()
