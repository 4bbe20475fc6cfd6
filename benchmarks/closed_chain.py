"""Closed chains: microseconds per sample per residual-and-Jacobian pass, Stewart 6-6 through its URDF loop constraints.

Run:  OMP_NUM_THREADS=1 python benchmarks/closed_chain.py [--samples 1000] [--repeats 3] [--profile]
(from a worktree other than the installed checkout, with PYTHONPATH=. so that this tree's robocal is measured)

Prints one table, every figure measured in this process, one thread:
  (a) the per-sample path (robocal.model.kinematics.SampleState: damped Newton assembly and implicit-function
      derivatives sample by sample, what Problem.evaluate ran for closed chains before the batched path);
  (b) the batched path (robocal.model.closed_chain_batch, what Problem.evaluate runs now);
  (c) the floor: Pinocchio 4.1's constraint models for the same machine (six PointAnchorConstraintModel:
      computeJointJacobians, calc, getConstraintsJacobian) plus the tool frame's placement and Jacobian, called
      per sample from Python: one evaluation of the closure rows and their Jacobian. A per-sample Newton
      assembly needs at least two of these a pass (three after a typical step), before any parameter Jacobian.
Each timed phase starts from a collected heap (gc.collect): the per-sample path leaves ~10^5 objects whose
collection otherwise lands in the batched path's first passes (measured: 43.5 against 38.4 us a step pass).
Passes: "step" = Problem.evaluate() after a parameter step of 10 um per parameter from assembled warm starts
(best of --repeats, wall clock and CPU time of this process); "calibrate" = the mean over every
residual-and-Jacobian evaluation of one calibrate() run from the nominal model (42 parameters, true machine
N(0, 1 mm), noise-free poses), the first, cold pass included. Both paths fit the same data; the table gives the
largest relative difference of their residuals and Jacobians.
--profile adds where one step pass of (b) spends its time (cProfile, cumulative, us per sample).
"""
from __future__ import annotations

import argparse
import cProfile
import gc
import os
import pstats
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import robocal  # noqa: E402
import robocal.estimation.problem as problem_module  # noqa: E402
from robocal.estimation.calibrate import calibrate  # noqa: E402
from robocal.estimation.problem import Problem  # noqa: E402
from robocal.systems.stewart import calibration as sc, modes as sm  # noqa: E402

URDF = Path(__file__).resolve().parents[1] / "urdf" / "stewart_6_6.urdf"
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
    """(mean seconds per residual-and-Jacobian evaluation, their number, the fitted free values) of one
    calibrate() run (its residual-only evaluations are left out)."""
    times = []
    evaluate = problem.evaluate

    def timed(jacobian: bool = True):
        t0 = time.perf_counter()
        out = evaluate(jacobian)
        if jacobian:
            times.append(time.perf_counter() - t0)
        return out
    problem.evaluate = timed
    gc.collect()
    calibrate(problem)
    return float(np.mean(times)), len(times), problem.params.free_values()


def pinocchio_floor(robot, q: np.ndarray, repeats: int) -> tuple[float, float]:
    """(best seconds per sample, max |difference| from robocal's rows) of one constraint evaluation per sample
    with Pinocchio's constraint models, plus the tool frame's placement and LOCAL Jacobian."""
    model, loops = robot.model, robot.loops
    data = model.createData()
    models = pin.StdVec_ConstraintModel()
    for c in loops.closures:
        f1, f2 = (model.frames[model.getFrameId(name)] for name in (c.frame1, c.frame2))
        models.append(pin.PointAnchorConstraintModel(model, f1.parentJoint, f1.placement, f2.parentJoint,
                                                     f2.placement))
    datas = pin.StdVec_ConstraintData()
    for cm in models:
        datas.append(cm.createData())
    tool, local = robot.frame_id("tool"), pin.ReferenceFrame.LOCAL

    def evaluate(qi):
        pin.computeJointJacobians(model, data, qi)
        for cm, cd in zip(models, datas):
            cm.calc(model, data, cd)
        c = np.concatenate([cd.extract().constraint_position_error for cd in datas])
        jac = pin.getConstraintsJacobian(model, data, models, datas)
        pin.updateFramePlacement(model, data, tool)
        return c, jac, pin.getFrameJacobian(model, data, tool, local)

    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for qi in q:
            evaluate(qi)
        best = min(best, (time.perf_counter() - t0) / len(q))
    worst = 0.0
    for qi in q[:50]:
        c, jac, _ = evaluate(qi)
        c_ref, jac_ref = loops.constraint_jacobian(model, model.createData(), qi)
        worst = max(worst, np.abs(c - c_ref).max(), np.abs(jac - jac_ref).max())
    return best, worst


PHASES = {("closed_chain_batch.py", "__init__"): "whole batched assembly and sensitivities",
          ("closure_groups.py", "closure_state"): "  closure evaluations (FK, rows, C_s)",
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
    profiler = cProfile.Profile()
    profiler.runcall(problem.evaluate)
    stats = pstats.Stats(profiler).stats
    found = {}
    for (path, _, name), (_, _, _, cumulative, _) in stats.items():
        key = (Path(path).name, name)
        if key in PHASES:
            found[PHASES[key]] = found.get(PHASES[key], 0.0) + cumulative
    return [(label, found.get(label, 0.0) / n * 1e6) for label in PHASES.values()]


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--profile", action="store_true", help="where one batched step pass spends its time")
    args = parser.parse_args()
    n = args.samples
    robot = robocal.load_urdf(URDF)
    rows, evaluations = [], {}
    for label, batched in (("(a) per-sample path", False), ("(b) batched path", True)):
        use_batched(batched)
        problem, truth = stewart_problem(robot, n)
        t_step, cpu_step, evaluations[batched] = step_pass(problem, args.repeats)
        problem, truth = stewart_problem(robot, n)
        t_fit, count, fitted = calibrate_passes(problem)
        rows.append((label, t_step / n * 1e6, cpu_step / n * 1e6, t_fit / n * 1e6, count,
                     np.abs(fitted - truth).max()))
    use_batched(True)
    q = np.array(list(problem.warm_starts.values()))
    t_floor, agreement = pinocchio_floor(robot, q, args.repeats)
    a, b = evaluations[False], evaluations[True]
    print(f"Closed chain: Stewart 6-6 ({URDF.name}, 6 point closures, 18 rows), 42 parameters, pose residuals, "
          f"{n} samples, pin {pin.__version__}, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}")
    print(f"{'path':<46}{'step pass':>12}{'(CPU)':>8}{'calibrate pass':>16}{'passes':>8}{'max param error':>17}")
    print(f"{'':<46}{'us/sample':>12}{'':>8}{'us/sample':>16}{'':>8}{'m':>17}")
    for label, step, cpu, fit, count, err in rows:
        print(f"{label:<46}{step:>12.1f}{cpu:>8.1f}{fit:>16.1f}{count:>8d}{err:>17.2e}")
    print(f"{'(c) floor: Pinocchio constraint models + FK':<46}{t_floor * 1e6:>12.1f}   (one evaluation)")
    print(f"speed-up (a)/(b): step {rows[0][1] / rows[1][1]:.1f}x, calibrate {rows[0][3] / rows[1][3]:.1f}x; "
          f"(b) / floor: step {rows[1][1] / (t_floor * 1e6):.1f}x")
    print(f"(b) vs (a), step pass: residuals {relative(b.r, a.r):.1e}, Jacobian {relative(b.J, a.J):.1e} relative; "
          f"floor rows vs robocal's: {agreement:.1e}")
    if args.profile:
        print("\n(b) one step pass under cProfile (its overhead included), cumulative us/sample:")
        for label, us in profile_step(robot, n):
            print(f"  {label:<48}{us:>8.1f}")


if __name__ == "__main__":
    main()
