"""UR5 full calibration (identifiable placement parameters + tool + base) from 6D poses: speed table.

Run: OMP_NUM_THREADS=1 python benchmarks/serial_calibration.py
Times the solve (identifiability + Levenberg-Marquardt + covariance), not the data simulation.
"""
import os
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))   # this checkout's robocal, not an installed one
from synthetic_cases import ur5_pose_problem  # noqa: E402

from robocal.estimation.calibrate import calibrate  # noqa: E402
from robocal.design.simulate import perturb, simulate_measurements  # noqa: E402


def run(n_poses, repeats):
    times, its = [], []
    for k in range(repeats):
        rng = np.random.default_rng(k)
        problem = ur5_pose_problem(rng, n_poses)
        truth = perturb(problem.params, rng)
        simulate_measurements(problem, truth, rng)
        start = problem.params.copy()
        problem.params = start
        t0 = time.perf_counter()
        result = calibrate(problem)
        times.append(time.perf_counter() - t0)
        its.append(result.solve.nit)
        assert result.success
    # an evaluation is one residual + Jacobian pass; count them per solve from the record
    return min(times), int(np.median(its)), result


def main():
    print(f"{'poses':>7} {'rows':>7} {'params':>7} {'solve [ms]':>11} {'iterations':>11} {'ms/iteration':>13}")
    for n, reps in ((100, 5), (1000, 2), (10000, 1)):
        t, it, res = run(n, reps)
        print(f"{n:>7} {6 * n:>7} {len(res.estimated):>7} {1e3 * t:>11.1f} {it:>11d} {1e3 * t / max(it, 1):>13.2f}")


if __name__ == "__main__":
    main()
