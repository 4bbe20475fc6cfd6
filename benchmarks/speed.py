"""Speed of the residual-and-Jacobian pass against Pinocchio's floor, and fit times, measured in one run.

Run: OMP_NUM_THREADS=1 python benchmarks/speed.py [--baseline DIR]

Table 1, UR5 full calibration (joint offsets and placements, tool, base; 6D poses): microseconds per pose of
- Pinocchio's floor in this process: computeJointJacobians + updateFramePlacement + getFrameJacobian, and
  forwardKinematics + computeFrameKinematicRegressor (what the batched pass calls per pose);
- one residual-and-Jacobian pass, per-sample reference (tests/reference_evaluation.py) and batched
  (Problem.evaluate). A joint placement moves by 1e-9 rad before every pass, as in a fit, so nothing
  kept from the previous pass applies. Below 10000 poses each of the four is timed 5 times in a row
  (median), the four in turn, 3 times over (median).
Table 2, calibrate(): CPU time (wall in brackets), passes over the samples and solver iterations, batched vs
the reference evaluation (with today's solver), and with --baseline DIR the same fit run by another robocal tree
(e.g. `git archive <commit> robocal | tar -x -C DIR`) in a subprocess; against Pinocchio's FK + frame Jacobian
over the same poses once (CPU, best of 3): the whole fit in such passes, and per solver iteration (issue 37).
Table 3: TIAGo (examples/tiago_mocap/full_bl.yaml) calibrate() (CPU, passes) and the command line (wall;
robocal's bytecode compiled first, as pip leaves an installed package: benchmarks/cli_timing.py).
With --figaroh [--figaroh-venv PATH], Table 4 is benchmarks/tiago_figaroh_calibration.py run as a subprocess:
the same TIAGo fit against FIGAROH 1.0.2 (installed into its own virtual environment), 3 repeats.
Each figure is the median of 3 runs; the machine may be shared, so compare ratios within the run.
"""
import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

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
from robocal.workflows.setup import load_config  # noqa: E402
from cli_timing import robocal_cli_seconds  # noqa: E402
from figaroh_env import add_options, skip_message  # noqa: E402

REPEATS = 3
PASS_REPEATS = 5     # consecutive passes per variant and repeat, below 10000 poses
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


def pass_costs(problem):
    """Per-pose microseconds at the problem's readings, one of each per call, in this order: Pinocchio's
    FK + frame Jacobian, FK + frame kinematic regressor, the reference pass and the batched pass."""
    model = problem.robot.model
    data = model.createData()
    fid = problem.robot.frame_id("tool0")
    Q = np.array([problem.robot.configuration(problem.joint_names, v) for v in problem.values])
    local = pin.ReferenceFrame.LOCAL
    moved = problem.params["elbow_joint.rx"]

    def jacobian():
        for q in Q:
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacement(model, data, fid)
            pin.getFrameJacobian(model, data, fid, local)

    def regressor():
        for q in Q:
            pin.forwardKinematics(model, data, q)
            pin.computeFrameKinematicRegressor(model, data, fid, local)

    def reference():
        moved.value += 1e-9
        reference_evaluate(problem)

    def batched():
        moved.value += 1e-9
        problem.evaluate()
    # each variant PASS_REPEATS times in a row (median): a single call of ~0.1 ms is mostly timer and cache noise
    return [1e6 * median_time(f, PASS_REPEATS if len(Q) < 10000 else 1) / len(Q)
            for f in (jacobian, regressor, reference, batched)]


def fit_time(n, reference=False):
    """calibrate() on a fresh UR5 problem of n poses (batched, or the reference evaluation): wall and CPU
    seconds, passes over the samples (Problem.evaluate calls) and solver iterations."""
    problem = ur5_problem(n)
    passes = []
    evaluate = (lambda jacobian=True, pb=problem: reference_evaluate(pb, jacobian)) if reference else problem.evaluate
    problem.evaluate = lambda jacobian=True: passes.append(1) or evaluate(jacobian)
    t0, c0 = time.perf_counter(), time.process_time()
    result = calibrate(problem)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    assert result.solve.success
    return wall, cpu, len(passes), result.solve.nit


def baseline_fit_time(tree, n):
    env = dict(os.environ, ROBOCAL_BENCH_TREE=os.path.abspath(tree))
    run = subprocess.run([sys.executable, __file__, "--fit-only", str(n)], env=env, capture_output=True, text=True,
                         check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def floor_pass(n):
    """CPU seconds of Pinocchio's FK + frame Jacobian over n poses (computeJointJacobians, updateFramePlacement,
    getFrameJacobian per pose), best of 3: the floor a pass is compared with."""
    problem = ur5_problem(n)
    model, fid = problem.robot.model, problem.robot.frame_id("tool0")
    data = model.createData()
    Q = np.array([problem.robot.configuration(problem.joint_names, v) for v in problem.values])
    times = []
    for _ in range(3):
        c0 = time.process_time()
        for q in Q:
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacement(model, data, fid)
            pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL)
        times.append(time.process_time() - c0)
    return min(times)


def fit_times(baseline):
    """{n: {variant: (wall, cpu, passes, iterations)}} medians over REPEATS; the variants alternate within each
    repeat so that a change in the machine's load hits all of them alike."""
    out = {}
    for n in SIZES:
        runs = {"batched": [], "reference": [], "baseline": []}
        for _ in range(REPEATS):
            runs["batched"].append(fit_time(n))
            runs["reference"].append(fit_time(n, reference=True))
            if baseline:
                b = baseline_fit_time(baseline, n)
                runs["baseline"].append((b["wall"], b["cpu"], b["passes"], b["nit"]))
        out[n] = {k: tuple(np.median(np.array(v), axis=0)) if v else None for k, v in runs.items()}
        out[n]["floor"] = floor_pass(n)
    return out


def tiago_fit(reference):
    """(CPU seconds, passes) of calibrate() on the TIAGo config (in this warm process)."""
    setup = load_config(TIAGO)
    problem = setup.problem
    passes = []
    evaluate = (lambda jacobian=True, pb=problem: reference_evaluate(pb, jacobian)) if reference else problem.evaluate
    problem.evaluate = lambda jacobian=True: passes.append(1) or evaluate(jacobian)
    c0 = time.process_time()
    calibrate(problem, setup.options)
    return time.process_time() - c0, len(passes)


def tiago_times():
    """Medians: calibrate() batched (CPU s, passes), with the reference evaluation, and the command line end to end
    (wall s)."""
    runs = [(*tiago_fit(False), *tiago_fit(True), robocal_cli_seconds(Path(ROOT), Path(TIAGO)))
            for _ in range(REPEATS)]
    return np.median(np.array(runs), axis=0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", help="a robocal tree whose calibrate() is timed on the same UR5 fits")
    ap.add_argument("--fit-only", type=int, help=argparse.SUPPRESS)
    add_options(ap)
    args = ap.parse_args()
    if args.fit_only is not None:      # the --baseline subprocess: only what an older tree also has
        wall, cpu, passes, nit = fit_time(args.fit_only)
        print(json.dumps({"wall": wall, "cpu": cpu, "passes": passes, "nit": int(nit)}))
        return
    print("UR5 residual-and-Jacobian pass, us per pose (median of 3)")
    print(f"{'poses':>7} {'FK+Jac':>8} {'FK+reg':>8} {'reference':>10} {'batched':>9} {'batched/FK+Jac':>15} "
          f"{'reference/batched':>18}")
    for n in SIZES:
        problem = ur5_problem(n)
        f_jac, f_reg, ref, new = np.median([pass_costs(problem) for _ in range(REPEATS)], axis=0)
        print(f"{n:>7} {f_jac:>8.2f} {f_reg:>8.2f} {ref:>10.2f} {new:>9.2f} {new / f_jac:>15.2f} {ref / new:>18.1f}")
    print("\nUR5 calibrate(), ms (median of 3; CPU time of this process, wall in brackets). FK+Jac: Pinocchio's floor "
          "over the poses once (CPU, best of 3); per iteration: calibrate() CPU / (iterations x FK+Jac)")
    fits = fit_times(args.baseline)
    print(f"{'poses':>7} {'batched':>16} {'passes':>6} {'iter':>4} {'FK+Jac':>7} {'/FK+Jac':>8} {'/iteration':>10} "
          f"{'reference':>17} {'ref/batched':>11}" + (f" {'baseline':>17} {'passes':>6} {'base/batched':>12}"
                                                    if args.baseline else ""))
    for n, f in fits.items():
        (w, c, k, it), (rw, rc, _, _), floor = f["batched"], f["reference"], f["floor"]
        line = (f"{n:>7} {1e3 * c:>7.1f} ({1e3 * w:>6.1f}) {k:>6.0f} {it:>4.0f} {1e3 * floor:>7.1f} {c / floor:>8.1f} "
                f"{c / floor / it:>10.1f} {1e3 * rc:>7.1f} ({1e3 * rw:>7.1f}) {rc / c:>11.1f}")
        if args.baseline:
            bw, bc, bk, _ = f["baseline"]
            line += f" {1e3 * bc:>7.1f} ({1e3 * bw:>7.1f}) {bk:>6.0f} {bc / c:>12.1f}"
        print(line)
    new, passes, ref, _, cli = tiago_times()
    print(f"\nTIAGo full_bl (median of 3, CPU, warm process): calibrate() batched {1e3 * new:.1f} ms ({passes:.0f} "
          f"passes), reference {1e3 * ref:.1f} ms; `robocal calibrate --no-report` end to end {1e3 * cli:.0f} ms (wall)")
    if not args.figaroh:
        print(skip_message())
        return
    print(flush=True)      # before the child writes to the same stdout
    # a subprocess: that script puts this tree first on sys.path, which would shadow a --baseline tree here
    subprocess.run([sys.executable, os.path.join(HERE, "tiago_figaroh_calibration.py"), "--figaroh", "--figaroh-venv",
                    str(args.figaroh_venv), "--repeats", str(REPEATS)], check=True)


if __name__ == "__main__":
    main()
