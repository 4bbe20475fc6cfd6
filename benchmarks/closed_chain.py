"""Closed chains: microseconds per sample per residual-and-Jacobian pass, Stewart 6-6 through its URDF loop constraints.

Run:  OMP_NUM_THREADS=1 python benchmarks/closed_chain.py [--samples 1000] [--repeats 3] [--profile]
      [--baseline COMMIT] [--pairs 3]
(from a worktree other than the installed checkout, with PYTHONPATH=. so that this tree's robocal is measured)

Prints one table, every figure measured in this run, one thread:
  (a) the per-sample path (robocal.model.kinematics.SampleState: assembly and implicit-function derivatives
      sample by sample, what Problem.evaluate ran for closed chains before the batched path);
  (b) the batched path (robocal.model.closed_chain_batch, what Problem.evaluate runs now), this tree, in this
      process (its numba kernels when numba is installed) and in subprocesses: the numpy path (ROBOCAL_NO_NUMBA=1)
      and the numba path (robocal.model.closed_chain_compiled);
  (b0) the same batched pass of robocal at --baseline (default 2aa0703: before issue 34, "today's figure"),
      extracted with `git archive` and measured in a subprocess alternately with the two (b) subprocesses,
      --pairs times (best of each: the shared cores' other jobs make single runs noisy);
  (c) the floor: Pinocchio 4.1's constraint models for the same machine (six PointAnchorConstraintModel:
      computeJointJacobians, calc, getConstraintsJacobian; robocal.model.pinocchio_rows) plus the tool frame's
      placement and Jacobian, called per sample from Python: one evaluation of the closure rows and their Jacobian.
      A per-sample Newton assembly needs at least two of these a pass, before any parameter Jacobian.
Each timed phase starts from a collected heap (gc.collect): the per-sample path leaves ~10^5 objects whose
collection otherwise lands in the batched path's first passes (measured: 43.5 against 38.4 us a step pass).
Passes: "step" = Problem.evaluate() after a parameter step of 10 um per parameter from assembled warm starts
(best of --repeats, wall clock and CPU time of this process); "calibrate" = the mean over every
residual-and-Jacobian evaluation of one calibrate() run from the nominal model (42 parameters, true machine
N(0, 1 mm), noise-free poses), the first, cold pass included. Both paths fit the same data; the table gives the
largest relative difference of their residuals and Jacobians. Issue 34's target: a step pass of at most 10 us per
sample at 1000 samples (the last line says whether it is met, on CPU time).
--profile adds where one step pass of (b) spends its time: CPU time per phase (timers around its methods) and
cProfile's cumulative figures (on CPU time, its overhead included), us per sample.
The last line: wall time of a fresh process's first pass on --samples samples, numba compiling its kernels (empty
NUMBA_CACHE_DIR), numba loading them from that cache, and the numpy path.
"""
from __future__ import annotations

import argparse
import cProfile
import gc
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import robocal  # noqa: E402
import robocal.estimation.problem as problem_module  # noqa: E402
from robocal.estimation.calibrate import calibrate  # noqa: E402
from robocal.estimation.problem import Problem  # noqa: E402
from robocal.model.closure_groups import closure_groups, closure_state  # noqa: E402
from robocal.model.tree_arrays import TreeArrays  # noqa: E402
from robocal.systems.stewart import calibration as sc, modes as sm  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
URDF = ROOT / "urdf" / "stewart_6_6.urdf"
BASELINE = "2aa0703"        # the commit issue 34 started from
TOOL = sm.Tool(0.2, 0.003)
BATCHED = problem_module.supports_closed_batch


def use_batched(on: bool) -> None:
    """Switch Problem.evaluate between the two closed-chain paths (the batched one is the default)."""
    problem_module.supports_closed_batch = BATCHED if on else (lambda ms: False)


def stewart_problem(robot, n: int, seed: int = 0) -> tuple[Problem, np.ndarray]:
    """The 42-parameter pose fit of benchmarks/stewart_calibration.py on n samples; returns (problem, truth)."""
    rng = np.random.default_rng(seed)
    truth = sc.stewart_parameters()
    for p in truth:
        p.value = rng.normal(0.0, 1e-3)
    tips = sc.random_tips(n, rng)
    abc, R = sc.random_orientations(n, rng)
    struts = sc.struts(sc.geometry(robot, truth), sc.tip_to_platform(tips, R, TOOL))
    rows = np.column_stack([tips, abc])
    problem = Problem(robot, sc.stewart_parameters(), sc.actuated(robot), struts,
                      sm.pose_residuals("pose", robot, np.arange(n), rows, [1] * 6, TOOL, (1e-6, 1e-6)))
    return problem, np.array([p.value for p in truth])


def step_pass(problem: Problem, repeats: int):
    """Best wall and CPU time (s) of Problem.evaluate() after a 10 um step of every parameter, and the last
    evaluation. CPU time (this process only) leaves out the time other jobs on the shared cores take."""
    x0 = problem.params.free_values()
    gc.collect()        # the previous path's garbage collected here, not during this path's timed passes
    problem.evaluate()                              # assembled warm starts at x0
    rng, wall, cpu, ev = np.random.default_rng(1), [], [], None
    for _ in range(repeats):
        problem.params.set_free_values(x0)
        problem.evaluate()
        problem.params.set_free_values(x0 + rng.normal(0.0, 1e-5, len(x0)))
        t0, c0 = time.perf_counter(), time.process_time()
        ev = problem.evaluate()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu), ev


def calibrate_passes(problem: Problem):
    """(mean seconds per residual-and-Jacobian evaluation, their number, the fitted free values, mean CPU seconds)
    of one calibrate() run (its residual-only evaluations are left out)."""
    times, cpu = [], []
    evaluate = problem.evaluate

    def timed(jacobian: bool = True):
        t0, c0 = time.perf_counter(), time.process_time()
        out = evaluate(jacobian)
        if jacobian:
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        return out
    problem.evaluate = timed
    gc.collect()
    calibrate(problem)
    return float(np.mean(times)), len(times), problem.params.free_values(), float(np.mean(cpu))


def pinocchio_floor(robot, q: np.ndarray, repeats: int) -> tuple[float, float]:
    """(best seconds per sample, max |difference| from the batched path's rows) of one constraint evaluation per
    sample with Pinocchio's constraint models (robocal.model.pinocchio_rows), plus the tool frame's placement and
    LOCAL Jacobian."""
    model, loops = robot.model, robot.loops
    data = model.createData()
    rows = loops.pinocchio_rows(model)
    tool, local = robot.frame_id("tool"), pin.ReferenceFrame.LOCAL

    def evaluate(qi):
        c, jac = rows.rows_and_jacobian(model, data, qi)
        pin.updateFramePlacement(model, data, tool)
        return c, jac, pin.getFrameJacobian(model, data, tool, local)

    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for qi in q:
            evaluate(qi)
        best = min(best, (time.perf_counter() - t0) / len(q))
    tree = TreeArrays(model)
    state = closure_state(tree, closure_groups(model, loops, tree), loops.n_rows, loops.solved_v, q[:50])
    worst = 0.0
    for i, qi in enumerate(q[:50]):
        c, jac, _ = evaluate(qi)
        worst = max(worst, np.abs(c - state["c"][i]).max(), np.abs(jac[:, loops.solved_v] - state["Cs"][i]).max())
    return best, worst


def measure(n: int, repeats: int) -> dict:
    """The batched step and calibrate passes of the robocal on the path (this tree or a baseline's); "first": wall
    seconds of the process's first pass (numba's import and kernel compilation or cache load included)."""
    robot = robocal.load_urdf(URDF)
    problem, _ = stewart_problem(robot, n)
    t0 = time.perf_counter()
    problem.evaluate()
    first = time.perf_counter() - t0
    wall, cpu, _ = step_pass(problem, repeats)
    problem, truth = stewart_problem(robot, n)
    fit, count, fitted, fit_cpu = calibrate_passes(problem)
    return {"robocal": robocal.__file__, "first": first, "step": wall / n * 1e6, "step_cpu": cpu / n * 1e6,
            "calibrate": fit / n * 1e6, "calibrate_cpu": fit_cpu / n * 1e6, "passes": count,
            "error": float(np.abs(fitted - truth).max())}


def measured_in(tree: Path, n: int, repeats: int, **env_vars) -> dict:
    """`measure` run by this script in a subprocess whose robocal is the one in `tree` (and env_vars set)."""
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1", **env_vars)
    out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--measure", "--samples", str(n),
                          "--repeats", str(repeats)], env=env, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def today_and_now(commit: str, n: int, repeats: int, pairs: int) -> tuple[dict, dict, dict]:
    """Best figures of the baseline commit's batched pass, of this tree's numpy path (ROBOCAL_NO_NUMBA=1) and of
    its numba path, measured alternately."""
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        runs = {"then": [], "numpy": [], "now": []}
        for _ in range(pairs):
            runs["then"].append(measured_in(Path(tmp), n, repeats))
            runs["numpy"].append(measured_in(ROOT, n, repeats, ROBOCAL_NO_NUMBA="1"))
            runs["now"].append(measured_in(ROOT, n, repeats))
    best = {}
    for key, results in runs.items():
        best[key] = {k: (min(r[k] for r in results) if isinstance(results[0][k], float) else results[0][k])
                     for k in results[0]}
        assert Path(best[key]["robocal"]).parents[1] == (Path(tmp) if key == "then" else ROOT), best[key]["robocal"]
    return best["then"], best["numpy"], best["now"]


def first_pass_costs(n: int) -> tuple[float, float, float]:
    """Wall seconds of a fresh process's first batched pass on n samples: numba path compiling its kernels into an
    empty cache, numba path loading them from that cache, numpy path (ROBOCAL_NO_NUMBA=1)."""
    with tempfile.TemporaryDirectory() as cache:
        cold = measured_in(ROOT, n, 1, NUMBA_CACHE_DIR=cache)["first"]
        warm = measured_in(ROOT, n, 1, NUMBA_CACHE_DIR=cache)["first"]
    return cold, warm, measured_in(ROOT, n, 1, ROBOCAL_NO_NUMBA="1")["first"]


PHASES = {("closed_chain_batch.py", "__init__"): "whole batched assembly and sensitivities",
          ("closure_groups.py", "closure_state"): "  closure evaluations (FK, rows, C_s)",
          ("closed_chain_compiled.py", "state"): "  closure evaluations (FK, rows, C_s)",
          ("closed_chain_batch.py", "_assemble"): "  assembly: evaluations + damped Newton steps",
          ("closed_chain_batch.py", "_step"): "    Newton steps (6-UPS: block elimination)",
          ("closed_chain_batch.py", "_solver"): "  C_s^-1 and the regularity check",
          ("closed_chain_batch.py", "_parameter_rows"): "  C_theta (closure rows per parameter)",
          ("closed_chain_batch.py", "frame"): "frame poses and Jacobians",
          ("kinematics.py", "__init__"): "ModelState (the calibrated model copy)",
          ("problem.py", "evaluate"): "Problem.evaluate, all"}


def profile_step(robot, n: int) -> list[tuple[str, float]]:
    """Cumulative time (us per sample) of the main phases of one batched step pass, from cProfile."""
    problem, _ = stewart_problem(robot, n)
    x0 = problem.params.free_values()
    problem.evaluate()
    problem.params.set_free_values(x0 + np.random.default_rng(1).normal(0.0, 1e-5, len(x0)))
    gc.collect()
    profiler = cProfile.Profile(time.process_time)     # CPU time: the shared cores' other jobs left out
    profiler.runcall(problem.evaluate)
    stats = pstats.Stats(profiler).stats
    found = {}
    for (path, _, name), (_, _, _, cumulative, _) in stats.items():
        key = (Path(path).name, name)
        if key in PHASES:
            found[PHASES[key]] = found.get(PHASES[key], 0.0) + cumulative
    return [(label, found.get(label, 0.0) / n * 1e6) for label in dict.fromkeys(PHASES.values())]


TIMED = (("ClosedChainBatch", "__init__", "batched assembly and sensitivities"),
         ("ClosedChainBatch", "_state", "  closure evaluations (FK, rows, C_s)"),
         ("TreeArrays", "placements", "    tree placements (numpy path)"),
         ("TreeArrays", "motion_columns", "    joint-motion columns (numpy path)"),
         ("ClosedChainBatch", "_step", "  Newton steps"),
         ("ClosedChainBatch", "_solver", "  C_s^-1 and its regularity bound"),
         ("ClosedChainBatch", "_parameter_rows", "  C_theta (closure rows per parameter)"),
         ("ClosedChainBatch", "_predicted", "  predicted starts"),
         ("ClosedChainBatch", "frame", "frame poses and Jacobians"),
         ("Problem", "evaluate", "Problem.evaluate, all"))


def phases(robot, n: int, repeats: int) -> list[tuple[str, float]]:
    """CPU time (us per sample) of the main phases of a batched step pass: process_time around each method (the
    timers' own cost included; best of `repeats` passes)."""
    import robocal.model.closed_chain_batch as batch_module
    import robocal.model.tree_arrays as tree_module
    owners = {"ClosedChainBatch": batch_module.ClosedChainBatch, "TreeArrays": tree_module.TreeArrays,
              "Problem": Problem}
    spent: dict = {}
    originals = []
    for owner, name, label in TIMED:
        cls = owners[owner]
        original = getattr(cls, name)
        originals.append((cls, name, original))

        def timed(*args, _original=original, _label=label, **kwargs):
            t0 = time.process_time()
            try:
                return _original(*args, **kwargs)
            finally:
                spent[_label] = spent.get(_label, 0.0) + time.process_time() - t0
        setattr(cls, name, timed)
    try:
        problem, _ = stewart_problem(robot, n)
        x0, rng, best = problem.params.free_values(), np.random.default_rng(1), {}
        for _ in range(repeats):
            problem.params.set_free_values(x0)
            problem.evaluate()
            problem.params.set_free_values(x0 + rng.normal(0.0, 1e-5, len(x0)))
            spent.clear()
            gc.collect()
            problem.evaluate()
            for label, t in spent.items():
                best[label] = min(best.get(label, np.inf), t)
    finally:
        for cls, name, original in originals:
            setattr(cls, name, original)
    return [(label, best.get(label, 0.0) / n * 1e6) for _, _, label in TIMED]


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--profile", action="store_true", help="where one batched step pass spends its time")
    parser.add_argument("--baseline", default=BASELINE, help="commit whose batched pass is today's figure")
    parser.add_argument("--pairs", type=int, default=3, help="alternate baseline / this-tree runs")
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)   # the subprocesses' entry
    args = parser.parse_args()
    n = args.samples
    if args.measure:
        print(json.dumps(measure(n, args.repeats)))
        return
    then, numpy_path, now = today_and_now(args.baseline, n, args.repeats, args.pairs)
    robot = robocal.load_urdf(URDF)
    rows, evaluations = [], {}
    for label, batched in (("(a) per-sample path", False), ("(b) batched path, numba if installed", True)):
        use_batched(batched)
        problem, truth = stewart_problem(robot, n)
        t_step, cpu_step, evaluations[batched] = step_pass(problem, args.repeats)
        problem, truth = stewart_problem(robot, n)
        t_fit, count, fitted, cpu_fit = calibrate_passes(problem)
        rows.append((label, t_step / n * 1e6, cpu_step / n * 1e6, t_fit / n * 1e6, cpu_fit / n * 1e6, count,
                     np.abs(fitted - truth).max()))
    for label, r in ((f"(b0) batched path at {args.baseline} (today)", then),
                     ("(b) numpy path, this tree, subprocess", numpy_path),
                     ("(b) numba path, this tree, subprocess", now)):
        rows.append((label, r["step"], r["step_cpu"], r["calibrate"], r["calibrate_cpu"], r["passes"], r["error"]))
    use_batched(True)
    q = np.array(list(problem.warm_starts.values()))
    t_floor, agreement = pinocchio_floor(robot, q, args.repeats)
    a, b = evaluations[False], evaluations[True]
    print(f"Closed chain: Stewart 6-6 ({URDF.name}, 6 point closures, 18 rows), 42 parameters, pose residuals, "
          f"{n} samples, pin {pin.__version__}, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}")
    print(f"{'path':<46}{'step pass':>12}{'(CPU)':>8}{'calibrate pass':>16}{'(CPU)':>8}{'passes':>8}"
          f"{'max param error':>17}")
    print(f"{'':<46}{'us/sample':>12}{'':>8}{'us/sample':>16}{'':>8}{'':>8}{'m':>17}")
    for label, step, cpu, fit, fit_cpu, count, err in rows:
        print(f"{label:<46}{step:>12.1f}{cpu:>8.1f}{fit:>16.1f}{fit_cpu:>8.1f}{count:>8d}{err:>17.2e}")
    print(f"{'(c) floor: Pinocchio constraint models + FK':<46}{t_floor * 1e6:>12.1f}   (one evaluation)")
    print(f"speed-up (a)/(b): step {rows[0][1] / rows[1][1]:.1f}x, calibrate {rows[0][3] / rows[1][3]:.1f}x; "
          f"(b) / floor: step {rows[1][1] / (t_floor * 1e6):.1f}x")
    print(f"(b) vs (a), step pass: residuals {relative(b.r, a.r):.1e}, Jacobian {relative(b.J, a.J):.1e} relative; "
          f"Pinocchio's rows vs the batched path's: {agreement:.1e}")
    best = now["step_cpu"]
    ratio = then["calibrate_cpu"] / now["calibrate_cpu"]
    print(f"today -> this tree, numba path (CPU, best of {args.pairs} alternating runs): step {then['step_cpu']:.1f} "
          f"-> {now['step_cpu']:.1f} us/sample ({then['step_cpu'] / now['step_cpu']:.2f}x), calibrate "
          f"{then['calibrate_cpu']:.1f} -> {now['calibrate_cpu']:.1f} ({ratio:.2f}x); numpy path: step "
          f"{numpy_path['step_cpu']:.1f}, calibrate {numpy_path['calibrate_cpu']:.1f}; "
          f"target step pass <= 10 us/sample: {'met' if best <= 10.0 else 'not met'} ({best:.1f})")
    cold, warm, plain = first_pass_costs(n)
    print(f"first pass of a fresh process, {n} samples (wall): numba compiling its kernels {cold:.2f} s, numba from "
          f"its cache {warm:.2f} s, numpy path {plain:.2f} s")
    if args.profile:
        print("\n(b) one step pass, CPU time per phase (process_time around each method, best of --repeats), "
              "us/sample:")
        with_numba = phases(robot, n, args.repeats)
        os.environ["ROBOCAL_NO_NUMBA"] = "1"
        without = phases(robot, n, args.repeats)
        del os.environ["ROBOCAL_NO_NUMBA"]
        print(f"  {'':<48}{'numba':>8}{'numpy':>8}")
        for (label, us), (_, plain_us) in zip(with_numba, without):
            print(f"  {label:<48}{us:>8.1f}{plain_us:>8.1f}")
        print("\n(b) one step pass under cProfile (its overhead included), cumulative us/sample of CPU time:")
        for label, us in profile_step(robot, n):
            print(f"  {label:<48}{us:>8.1f}")


if __name__ == "__main__":
    main()
