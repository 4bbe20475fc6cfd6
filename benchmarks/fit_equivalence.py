"""The same fits, fewer passes: calibrate() on the shipped examples and on simulated UR5 problems, this tree
against another (issue 37), and the batched evaluation against the per-sample reference.

    OMP_NUM_THREADS=1 python benchmarks/fit_equivalence.py --baseline DIR [--quick]

DIR is another robocal tree (e.g. `git archive 41858cc robocal | tar -x -C DIR`), run in a subprocess on the same
problems. Per fit: the passes over the samples (Problem.evaluate calls) in both trees, the largest parameter
difference in units of its standard error, whether the kept set, the determinacy classes, refusals and
findings are the same, and (TIAGo examples) this tree's batched fit against its per-sample reference fit
(tests/reference_evaluation.py) as the largest difference relative to the largest parameter. --quick leaves out
the two slow per-sample examples (tilt_all, select_hand_sessions).
"""
import argparse
import glob
import json
import os
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
SLOW = ("hand_full_compliance_backlash_tilt_all", "select_hand_sessions")


def cases(quick: bool) -> list[str]:
    configs = sorted(glob.glob(str(ROOT / "examples" / "tiago_mocap" / "*.yaml")))
    configs += sorted(glob.glob(str(ROOT / "examples" / "closed_loops" / "*.yaml")))
    configs = [c for c in configs if not (quick and any(s in c for s in SLOW))]
    return configs + ["ur5 100 linear", "ur5 100 huber", "ur5 1000 linear", "ur5 1000 huber"]


def fit(case: str, reference: bool = False) -> dict:
    """In this process: calibrate() one case; what the comparison needs, JSON-ready."""
    sys.path.insert(0, os.environ.get("ROBOCAL_BENCH_TREE", str(ROOT)))
    sys.path.insert(1, str(ROOT / "tests"))
    import numpy as np
    from robocal.estimation.calibrate import CalibrationOptions, calibrate
    from robocal.estimation.problem import Problem
    if case.startswith("ur5"):
        from synthetic_cases import ur5_pose_problem
        from robocal.design.simulate import perturb, simulate_measurements
        _, n, loss = case.split()
        rng = np.random.default_rng(0)
        problem = ur5_pose_problem(rng, int(n))
        simulate_measurements(problem, perturb(problem.params, rng), rng)
        problem.params, options = problem.params.copy(), CalibrationOptions(loss=loss)
    else:
        from robocal.workflows.setup import load_config
        setup = load_config(case)
        problem, options = setup.problem, setup.options
    passes = []
    if reference:
        from reference_evaluation import reference_evaluate
        problem.evaluate = lambda jacobian=True: passes.append(1) or reference_evaluate(problem, jacobian)
    else:
        evaluate = Problem.evaluate
        Problem.evaluate = lambda self, jacobian=True: passes.append(1) or evaluate(self, jacobian)
    result = calibrate(problem, options)
    p = result.params
    return {"values": {q.name: q.value for q in p}, "stderr": {q.name: q.stderr for q in p},
            "independent": list(result.selection.independent), "classes": dict(result.determinacy.classes),
            "refusals": [str(r) for r in result.refusals], "findings": [f.describe() for f in result.findings],
            "passes": len(passes), "nit": int(result.solve.nit), "message": result.solve.message}


def fit_process(case: str, tree: str | None = None, reference: bool = False) -> dict:
    env = dict(os.environ, ROBOCAL_BENCH_TREE=os.path.abspath(tree)) if tree else dict(os.environ)
    cmd = [sys.executable, __file__, "--child", case] + (["--reference"] if reference else [])
    run = subprocess.run(cmd, capture_output=True, text=True, check=True, env=env)
    return json.loads(run.stdout.strip().splitlines()[-1])


def in_stderrs(a: dict, b: dict) -> float:
    worst = 0.0
    for name, v in a["values"].items():
        se = a["stderr"].get(name)
        if se and se > 0 and se != float("inf"):
            worst = max(worst, abs(v - b["values"][name]) / se)
    return worst


def relative(a: dict, b: dict) -> float:
    names = list(a["values"])
    scale = max(abs(b["values"][n]) for n in names) or 1.0
    return max(abs(a["values"][n] - b["values"][n]) for n in names) / scale


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", required=False, help="the other robocal tree")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--reference", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(fit(args.child, args.reference)))
        return
    print("| fit | passes (baseline -> this) | iterations | largest difference, standard errors | same selection, "
          "classes, refusals, findings | batched vs per-sample reference, relative |")
    print("|---|---|---|---:|---|---:|")
    for case in cases(args.quick):
        new = fit_process(case)
        base = fit_process(case, args.baseline) if args.baseline else new
        same = all(base[k] == new[k] for k in ("independent", "classes", "refusals", "findings"))
        ref = ""
        if "tiago_mocap" in case:
            ref = f"{relative(new, fit_process(case, reference=True)):.1e}"
        label = Path(case).name if case.endswith(".yaml") else case
        print(f"| {label} | {base['passes']} -> {new['passes']} | {base['nit']} -> {new['nit']} | "
              f"{in_stderrs(base, new):.1e} | {'yes' if same else 'NO'} | {ref} |", flush=True)


if __name__ == "__main__":
    main()
