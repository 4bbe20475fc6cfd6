"""Where a camera pose plan spends its time (robocal plan on a camera block, docs/camera.md "Pose design").

UR5, eye-in-hand camera 1280 x 1024, 9 x 6 checkerboard: K candidate viewpoints (IK on the nominal robot), the
design matrix (every corner at every candidate: 108 rows per candidate), then the choice of N poses. The choice
is timed twice in the same run on the same design: the baseline keeps each candidate's full rows (108 x L blocks,
as before robocal.design.selection kept a tall block as the R of its QR), the current code the L x L R; both must
choose the same poses.

Run:  OMP_NUM_THREADS=1 python benchmarks/camera_plan.py [--candidates 300] [--poses 30]
Times are wall clock, one thread, one run.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))     # the simulated scenes of the tests

import numpy as np  # noqa: E402

from camera_cases import CAMERA, K_TRUE, SEED_READING, TARGET, W_TRUE, X_TRUE  # noqa: E402
from robocal import load_example  # noqa: E402
from robocal.design.camera_poses import camera_candidates, camera_design_problem  # noqa: E402
from robocal.design.selection import DesignMatrix, select_poses  # noqa: E402
from robocal.io.camera_target import target_from_dict  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--candidates", type=int, default=300)
    ap.add_argument("--poses", type=int, default=30)
    args = ap.parse_args(argv)
    robot = load_example("ur5")
    robot.add_frame("camera", "tool0", X_TRUE)
    target = target_from_dict(TARGET)
    t = time.perf_counter()
    found = camera_candidates(robot, robot.joint_names, "camera", "eye_in_hand", W_TRUE, target, CAMERA, K_TRUE,
                              args.candidates, np.random.default_rng(0), SEED_READING)
    t_ik = time.perf_counter() - t
    t = time.perf_counter()
    problem = camera_design_problem(robot, robot.joint_names, found.values, "camera", "eye_in_hand", W_TRUE, target,
                                    CAMERA, K_TRUE, sigma=0.3)
    design = DesignMatrix.from_problem(problem)
    t_design = time.perf_counter() - t
    full = DesignMatrix.from_problem(problem)
    full.blocks = np.zeros((full.n_candidates, int(full.rows.max()), len(full.base.independent)))
    cols = full.base.independent
    for k, u in enumerate(full.units):
        full.blocks[k, :len(u)] = full.J[np.ix_(u, cols)] / full.scale
    print(f"# Camera pose plan: {len(found.values)} candidates ({found.dropped}), {design.J.shape[0]} rows x "
          f"{len(cols)} identifiable columns, choose {args.poses}\n")
    print(f"candidates (IK): {t_ik:.2f} s; design matrix: {t_design:.2f} s\n")
    print("| criterion | full rows (s) | R of QR (s) | speed-up | same poses |\n|---|---|---|---|---|")
    for criterion in ("D", "A", "E"):
        t = time.perf_counter()
        a = select_poses(full, args.poses, criterion)
        t_full = time.perf_counter() - t
        t = time.perf_counter()
        b = select_poses(design, args.poses, criterion)
        t_qr = time.perf_counter() - t
        print(f"| {criterion} | {t_full:.2f} | {t_qr:.2f} | {t_full / t_qr:.1f}x | "
              f"{'yes' if list(a.chosen) == list(b.chosen) else 'NO'} |")


if __name__ == "__main__":
    main()
