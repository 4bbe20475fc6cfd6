"""Speed of the residual-and-Jacobian pass against Pinocchio's floor, and fit times, measured in one run.

Run: OMP_NUM_THREADS=1 python benchmarks/speed.py [--baseline DIR]

Table 1, UR5 full calibration (joint offsets and placements, tool, base; 6D poses): microseconds per pose of
- Pinocchio's floor in this process: computeJointJacobians + updateFramePlacement + getFrameJacobian, and
  forwardKinematics + computeFrameKinematicRegressor (what the batched pass calls per pose);
- one residual-and-Jacobian pass, per-sample reference (tests/reference_evaluation.py) and batched
  (Problem.evaluate). A joint placement moves by 1e-9 rad before every pass, as in a fit, so nothing
  kept from the previous pass applies.
Table 2, calibrate() wall time: batched vs the reference evaluation (with today's solver), and with
--baseline DIR the same fit run by another robocal tree (e.g. `git archive <commit> robocal | tar -x -C DIR`)
in a subprocess. Table 3: TIAGo (examples/tiago_mocap/full_bl.yaml) calibrate() and the command line.
FIGAROH is not timed here: installing it into its own virtual environment is not implemented yet.
Each figure is the median of 3 runs; the machine may be shared, so compare ratios within the run.
"""
import argparse
import json
import os
import subprocess
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "tests"))
sys.path.insert(0, os.environ.get("ROBOCAL_BENCH_TREE", ROOT))     # --baseline runs another tree's robocal
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

from reference_evaluation import reference_evaluate  # noqa: E402
from synthetic_cases import ur5_pose_problem  # noqa: E402
from robocal.design.simulate import perturb, simulate_measurements  # noqa: E402
from robocal.estimation.calibrate import calibrate  # noqa: E402
from robocal.io.config import load_config  # noqa: E402

REPEATS = 3
SIZES = (100, 1000, 10000)
TIAGO = os.path.join(ROOT, "examples", "tiago_mocap", "full_bl.yaml")


def median_time(f, repeats=REPEATS):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def ur5_problem(n, seed=0):
    rng = np.random.default_rng(seed)
    problem = ur5_pose_problem(rng, n)
    simulate_measurements(problem, perturb(problem.params, rng), rng)
    problem.params = problem.params.copy()
    return problem


def floors(problem):
    """Pinocchio's per-pose cost from Python at the problem's readings (us): (FK + frame Jacobian,
    FK + frame kinematic regressor)."""
    model = problem.robot.model
    data = model.createData()
    fid = problem.robot.frame_id("tool0")
    Q = np.array([problem.robot.configuration(problem.joint_names, v) for v in problem.values])
    local = pin.ReferenceFrame.LOCAL

    def jacobian():
        for q in Q:
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacement(model, data, fid)
            pin.getFrameJacobian(model, data, fid, local)

    def regressor():
        for q in Q:
            pin.forwardKinematics(model, data, q)
            pin.computeFrameKinematicRegressor(model, data, fid, local)
    return 1e6 * median_time(jacobian) / len(Q), 1e6 * median_time(regressor) / len(Q)


def pass_time(problem, evaluate):
    p = problem.params["elbow_joint.rx"]

    def one():
        p.value += 1e-9
        evaluate(problem)
    return 1e6 * median_time(one) / len(problem.values)


def fit_times(reference: bool):
    """{n: median calibrate() seconds} for the UR5 sizes (fresh start parameters each run)."""
    out = {}
    for n in SIZES:
        times = []
        for _ in range(REPEATS):
            problem = ur5_problem(n)
            if reference:
                problem.evaluate = lambda jacobian=True, pb=problem: reference_evaluate(pb, jacobian)
            t0 = time.perf_counter()
            result = calibrate(problem)
            times.append(time.perf_counter() - t0)
            assert result.solve.success
        out[n] = float(np.median(times))
    return out


def baseline_fit_times(tree):
    env = dict(os.environ, ROBOCAL_BENCH_TREE=os.path.abspath(tree))
    run = subprocess.run([sys.executable, __file__, "--fit-only"], env=env, capture_output=True, text=True,
                         check=True)
    return {int(k): v for k, v in json.loads(run.stdout.strip().splitlines()[-1]).items()}


def tiago_times():
    fits = {}
    for label, reference in (("batched", False), ("reference", True)):
        times = []
        for _ in range(REPEATS):
            setup = load_config(TIAGO)
            problem = setup.problem
            if reference:
                problem.evaluate = lambda jacobian=True, pb=problem: reference_evaluate(pb, jacobian)
            t0 = time.perf_counter()
            calibrate(problem, setup.options)
            times.append(time.perf_counter() - t0)
        fits[label] = float(np.median(times))
    out = os.path.join("/tmp", f"robocal_speed_{os.getpid()}")
    cmd = [sys.executable, "-c", "import sys; sys.path.insert(0, sys.argv[1]); from robocal.cli.main import main; "
           "sys.exit(main(sys.argv[2:]))", ROOT, "calibrate", TIAGO, "-o", out, "--force", "--no-report", "-q"]
    cli = median_time(lambda: subprocess.run(cmd, check=True, capture_output=True))
    return fits, cli


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", help="a robocal tree whose calibrate() is timed on the same UR5 fits")
    ap.add_argument("--fit-only", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.fit_only:      # the --baseline subprocess: only what an older tree also has
        print(json.dumps(fit_times(reference=False)))
        return
    print("UR5 residual-and-Jacobian pass, us per pose (median of 3)")
    print(f"{'poses':>7} {'FK+Jac':>8} {'FK+reg':>8} {'reference':>10} {'batched':>9} {'batched/FK+Jac':>15} "
          f"{'reference/batched':>18}")
    for n in SIZES:
        problem = ur5_problem(n)
        f_jac, f_reg = floors(problem)
        ref = pass_time(problem, reference_evaluate)
        new = pass_time(problem, lambda pb: pb.evaluate())
        print(f"{n:>7} {f_jac:>8.2f} {f_reg:>8.2f} {ref:>10.2f} {new:>9.2f} {new / f_jac:>15.2f} {ref / new:>18.1f}")
    print("\nUR5 calibrate() wall time, ms (median of 3)")
    new, ref = fit_times(False), fit_times(True)
    base = baseline_fit_times(args.baseline) if args.baseline else None
    print(f"{'poses':>7} {'batched':>9} {'reference':>10} {'ref/batched':>12}"
          + (f" {'baseline':>9} {'baseline/batched':>17}" if base else ""))
    for n in SIZES:
        line = f"{n:>7} {1e3 * new[n]:>9.1f} {1e3 * ref[n]:>10.1f} {ref[n] / new[n]:>12.1f}"
        if base:
            line += f" {1e3 * base[n]:>9.1f} {base[n] / new[n]:>17.1f}"
        print(line)
    fits, cli = tiago_times()
    print(f"\nTIAGo full_bl calibrate(): batched {1e3 * fits['batched']:.1f} ms, reference "
          f"{1e3 * fits['reference']:.1f} ms; `robocal calibrate --no-report` end to end {1e3 * cli:.0f} ms")
    print("FIGAROH comparison: not implemented in this script (see the module doc)")


if __name__ == "__main__":
    main()
