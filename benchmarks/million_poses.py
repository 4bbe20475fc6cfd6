"""UR5 full calibration from a very large number of simulated 6D poses: calibrate() on its chunked path.

Run: OMP_NUM_THREADS=1 python benchmarks/million_poses.py [--poses 1000000] [--chunk 20000]
Prints the time of each stage and the process's maximum resident memory (resource.getrusage), which is the
figure that matters: the Jacobian (6 rows a pose) is never held whole (robocal.estimation.chunked_lstsq).
The fit is calibrate() itself, every stage included (registration for the "before" figures, the default
prior's evidence, selection, Levenberg-Marquardt, covariance, determinacy classes), with chunk_terms = --chunk.
"""
import argparse
import os
import resource
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))   # this checkout's robocal, not an installed one
import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from robocal import load_example  # noqa: E402
from robocal.design.simulate import perturb, random_configurations  # noqa: E402
from robocal.estimation.calibrate import CalibrationOptions, calibrate  # noqa: E402
from robocal.estimation.problem import Problem  # noqa: E402
from robocal.model.batch_kinematics import BatchKinematics  # noqa: E402
from robocal.model.parameters import robot_parameters  # noqa: E402
from robocal.residuals import PoseResidual  # noqa: E402

SIGMA = 5e-5   # m and rad


def max_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0   # Linux reports kB


def build(n, rng, chunk):
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True)
    values = random_configurations(robot, joints, n, rng)
    res = PoseResidual("tracker", "tool0", np.arange(n), np.tile([0, 0, 0, 0, 0, 0, 1.0], (n, 1)), sigma=SIGMA)
    problem = Problem(robot, params, joints, values, [res])
    truth = perturb(params, rng)
    problem.params = truth          # simulate on the true robot, a chunk at a time
    ms = problem.model_state()
    kin = BatchKinematics(ms, problem.sample_constants(ms), problem.values, None)
    meas = np.empty((n, 7))
    for k0 in range(0, n, chunk):
        idx = np.arange(k0, min(k0 + chunk, n))
        fa = kin.frame("tool0", idx)
        meas[idx, :3] = fa.p + rng.normal(0.0, SIGMA, (len(idx), 3))
        rot = Rotation.from_rotvec(rng.normal(0.0, SIGMA, (len(idx), 3))) * Rotation.from_matrix(fa.R)
        meas[idx, 3:] = rot.as_quat()                     # x y z w
    res.set_measurements(meas)
    problem.params = params
    return problem, truth


def fit(problem, chunk):
    result = calibrate(problem, CalibrationOptions(chunk_terms=chunk))
    return result


def prediction_error(problem, truth, rng, n=1000):
    """Largest tool position difference between the fitted and the true robot at fresh configurations (the
    parameters the data cannot separate are regrouped, so they are compared through what they predict)."""
    values = random_configurations(problem.robot, problem.joint_names, n, rng)
    poses = []
    for params in (problem.params, truth):
        check = Problem(problem.robot, params, problem.joint_names, values, [])
        ms = check.model_state()
        poses.append(BatchKinematics(ms, check.sample_constants(ms), values, None).frame("tool0", np.arange(n)).p)
    return float(np.abs(poses[0] - poses[1]).max())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=1_000_000)
    ap.add_argument("--chunk", type=int, default=20_000, help="terms (poses) per chunk")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    problem, truth = build(args.poses, rng, args.chunk)
    t1 = time.perf_counter()
    rss_built = max_rss_mb()
    result = fit(problem, args.chunk)
    t2 = time.perf_counter()
    err = prediction_error(problem, truth, np.random.default_rng(1))
    sol, selection = result.solve, result.selection
    se = [problem.params[n].stderr for n in problem.params.free_names]
    print(f"poses {args.poses}, rows {6 * args.poses}, parameters {selection.rank} of {len(selection.names)} "
          f"identifiable, chunk {args.chunk} poses")
    print(f"build + simulate   {t1 - t0:8.1f} s   max RSS so far {rss_built:8.0f} MB")
    print(f"calibrate()        {t2 - t1:8.1f} s   {sol.nit} iterations, {sol.message}; residual/sigma "
          f"{np.sqrt(result.sigma2):.4f}; status {result.status}; standard errors {min(se):.2e}..{max(se):.2e}; "
          f"default prior applied: {result.default_prior.applied}; before {result.before[0].headline()}, "
          f"after {result.after[0].headline()}")
    print(f"max RSS            {max_rss_mb():8.0f} MB")
    print(f"tool position error against the true robot, 1000 fresh configurations: max {1e6 * err:.2f} um "
          f"(noise {1e6 * SIGMA:.0f} um a pose)")


if __name__ == "__main__":
    main()
