"""Where one calibrate() spends its time: CPU per stage and per pass, each fit in a fresh process (issue 37).

    OMP_NUM_THREADS=1 python benchmarks/fit_profile.py [--config examples/tiago_mocap/full_bl.yaml | --ur5 N]
                                                      [--runs 8] [--gc-off] [--tree DIR]

Each run is a new process (as the FIGAROH comparison times it: the first calibrate() of a process pays the
first calls of its LAPACK and numpy routines and of Pinocchio's Data); the stages are timed by wrapping the
functions calibrate() calls (a few microseconds each), the passes by wrapping Problem.evaluate. Medians over
the runs. --gc-off runs the fits with Python's garbage collector disabled, to show what its collections cost.
"""
import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
STAGES = ("physical_scales", "register_nominal", "apply_default_prior", "select_base_parameters", "_apply_selection",
          "levenberg_marquardt", "triangle", "columns_triangle", "block_statistics", "covariance", "classify",
          "check_fit", "find")


def one_fit(config: str | None, ur5: int | None, gc_off: bool, tree: str | None = None) -> dict:
    """In this process: build the problem, time calibrate() by stage and by pass (CPU seconds). tree: the robocal
    tree to import (default this one)."""
    sys.path.insert(0, tree or str(ROOT))
    sys.path.insert(1, str(ROOT / "tests"))
    import numpy as np
    import robocal.estimation.calibrate as calibrate_module
    from robocal.estimation.problem import Problem
    if ur5:
        from synthetic_cases import ur5_pose_problem
        from robocal.design.simulate import perturb, simulate_measurements
        rng = np.random.default_rng(0)
        problem = ur5_pose_problem(rng, ur5)
        simulate_measurements(problem, perturb(problem.params, rng), rng)
        problem.params, options = problem.params.copy(), None
    else:
        from robocal.workflows.setup import load_config
        setup = load_config(config)
        problem, options = setup.problem, setup.options
    stages, passes = {}, []

    def timed(name, fn):
        def wrapper(*args, **kwargs):
            c0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                stages[name] = stages.get(name, 0.0) + time.process_time() - c0
        return wrapper

    for name in STAGES:
        if hasattr(calibrate_module, name):
            setattr(calibrate_module, name, timed(name, getattr(calibrate_module, name)))
    evaluate = Problem.evaluate

    def counted(self, jacobian=True):
        c0 = time.process_time()
        try:
            return evaluate(self, jacobian)
        finally:
            passes.append((len(self.params.free_names), time.process_time() - c0))
    Problem.evaluate = counted
    if gc_off:
        import gc
        gc.disable()
    c0 = time.process_time()
    result = calibrate_module.calibrate(problem, options)
    total = time.process_time() - c0
    return {"total": total, "stages": stages, "passes": passes, "iterations": int(result.solve.nit)}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(ROOT / "examples" / "tiago_mocap" / "full_bl.yaml"))
    ap.add_argument("--ur5", type=int, help="a simulated UR5 pose calibration of N poses instead of --config")
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--gc-off", action="store_true")
    ap.add_argument("--tree", help="profile another robocal tree (e.g. `git archive <commit> robocal | tar -x -C DIR`)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(one_fit(args.config, args.ur5, args.gc_off, args.tree)))
        return
    import numpy as np
    cmd = ([sys.executable, __file__, "--child", "--config", args.config]
           + (["--ur5", str(args.ur5)] if args.ur5 else []) + (["--gc-off"] if args.gc_off else [])
           + (["--tree", os.path.abspath(args.tree)] if args.tree else []))
    runs = [json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout.strip().splitlines()[-1])
            for _ in range(args.runs)]
    ms = lambda v: 1e3 * float(np.median(v))       # noqa: E731
    what = (f"UR5, {args.ur5} poses" if args.ur5 else args.config) + (f" (robocal of {args.tree})" if args.tree else "")
    print(f"{what}: calibrate() {ms([r['total'] for r in runs]):.2f} ms CPU (median of {args.runs} fresh processes"
          f"{', garbage collector off' if args.gc_off else ''}), {len(runs[0]['passes'])} passes, "
          f"{runs[0]['iterations']} iterations")
    print("| stage (nested: the solvers hold their passes, the registration its solver) | ms |\n|---|---:|")
    for name in STAGES:
        if name in runs[0]["stages"]:
            print(f"| {name} | {ms([r['stages'].get(name, 0.0) for r in runs]):.2f} |")
    print(f"| all passes | {ms([sum(t for _, t in r['passes']) for r in runs]):.2f} |")
    print("\npasses in order: free columns, ms (median)")
    print(", ".join(f"{cols}: {ms([r['passes'][k][1] for r in runs]):.2f}"
                    for k, (cols, _) in enumerate(runs[0]["passes"])))


if __name__ == "__main__":
    main()
