"""Closed-chain assembly: Pinocchio's constraint-projected solve against robocal's Newton, at equal accuracy.

Run:  OMP_NUM_THREADS=1 python benchmarks/closed_chain_assembly.py [--samples 300] [--repeats 3]
(from a worktree other than the installed checkout, with PYTHONPATH=. so that this tree's robocal is measured)

Assembly solves the passive joints of a closed chain for given actuated readings (closed-chain forward
kinematics). The machine is the Stewart 6-6 of urdf/stewart_6_6.urdf (six point closures, 18 rows, 18 passive
coordinates); the readings are the closed-form inverse kinematics of random workspace poses. Every method stops
at the same test, max |c| < 1e-12 (m), and the table gives the worst |c| reached and the largest difference of its
solutions from the closed form's configuration, so the times compare equal accuracy. Times are CPU time of this
process (best of --repeats, microseconds per sample, one thread). Methods:

  (p) Pinocchio's constraint-projected solve, the loop of Pinocchio's closed-loop examples: computeJointJacobians,
      `calc` of each PointAnchorConstraintModel, getConstraintsJacobian, the least-squares step on the passive
      coordinates (-J_s^+ c: np.linalg.solve, J_s being square here), pin.integrate; one sample at a time;
  (d) robocal's damped Newton alone (robocal.model.inverse_kinematics.damped_newton, what `assemble` ran before
      issue 34) on the same Pinocchio rows: damping mu = |c|^2, Armijo line search, an SVD regularity check at
      the solution; one sample at a time;
  (a) `robocal.model.assemble` now (robocal.model.projected_assembly): (p)'s lean loop with (d)'s step (damped by
      |c|^2, plain below |c|^2 = 1e-20), each kept if it lowers |c|^2 enough, (d) from the same start otherwise,
      and the regularity check screened by a rigorous bound before any SVD; one sample at a time;
  (b) robocal's batched Newton (robocal.model.closed_chain_batch, what a calibration pass runs): the same damped
      steps on all samples at once as whole-array numpy, C_s^-1 and its regularity check included.

Two starts: "cold" from the neutral configuration (the first pass of a calibration), "warm" from the solution of
the readings 1 mm away on every strut (every later pass, and a trajectory).

Equal accuracy is not yet the same answer: a second table sweeps the crank of the MJCF four-bar of
examples/closed_loops/fourbar.xml over its range from the neutral (drawn) start, cold each time, and counts the
readings each method assembles on the drawn branch (the one a warm-started sweep follows).
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import robocal  # noqa: E402
from robocal.model import ModelState, ParameterSet, assemble  # noqa: E402
from robocal.model.closed_chain_batch import ClosedChainBatch  # noqa: E402
from robocal.model.inverse_kinematics import damped_newton  # noqa: E402
from robocal.systems.stewart import mechanism as sm  # noqa: E402

URDF = Path(__file__).resolve().parents[1] / "urdf" / "stewart_6_6.urdf"
FOURBAR = Path(__file__).resolve().parents[1] / "examples" / "closed_loops" / "fourbar.xml"
TOL = 1e-12


def pinocchio_projection(model, data, constraints, datas, views, passive, q, tol=TOL, max_iterations=50):
    """(q, iterations): Pinocchio's projection onto the constraint manifold, actuated coordinates held."""
    for it in range(max_iterations + 1):
        pin.computeJointJacobians(model, data, q)
        for cm, cd in zip(constraints, datas):
            cm.calc(model, data, cd)
        c = np.concatenate([v.constraint_position_error for v in views])
        if np.abs(c).max() < tol:
            return q, it
        J = pin.getConstraintsJacobian(model, data, constraints, datas)
        dv = np.zeros(model.nv)
        dv[passive] = -np.linalg.solve(J[:, passive], c)
        q = pin.integrate(model, q, dv)
    raise RuntimeError("no convergence")


def projection_any(robot, q, tol=TOL, max_iterations=50):
    """(p) on any closure rows (least squares when J_s has more rows than unknowns)."""
    model, loops, data = robot.model, robot.loops, robot.model.createData()
    for _ in range(max_iterations + 1):
        c, J = loops.constraint_jacobian(model, data, q)
        if np.abs(c).max() < tol:
            return q
        dv = np.zeros(model.nv)
        dv[loops.solved_v] = -np.linalg.lstsq(J[:, loops.solved_v], c, rcond=None)[0]
        q = pin.integrate(model, q, dv)
    raise RuntimeError("no convergence")


def branch_table(points: int = 48) -> None:
    robot = robocal.load_mjcf(FOURBAR)
    model, loops = robot.model, robot.loops
    data = model.createData()
    cranks = np.linspace(*robot.limits(["crank"]), points).reshape(-1)
    drawn = {}
    for side in (cranks[cranks >= 0], cranks[cranks < 0][::-1]):     # warm-started sweeps out of the drawn pose
        q = robot.neutral()
        for value in side:
            q = drawn[value] = assemble(robot, model, [value], q_guess=q)
    rows = lambda q: loops.constraint_jacobian(model, data, q)  # noqa: E731
    retract = lambda q, v: pin.integrate(model, q, v)  # noqa: E731
    methods = {"(p) Pinocchio constraint-projected solve": lambda q0, v: projection_any(robot, q0),
               "(d) robocal damped Newton alone": lambda q0, v: damped_newton(rows, q0, retract, free=loops.solved_v),
               "(a) robocal assemble": lambda q0, v: assemble(robot, model, [v])}
    print(f"\nBranch from a cold start: {FOURBAR.name}, crank over its range ({points} readings), each from the "
          "neutral configuration (the drawn pose)")
    for label, solve in methods.items():
        kept = failed = 0
        for value in cranks:
            try:
                q = solve(loops.set_actuated(robot.neutral(), [value]), value)
            except (RuntimeError, robocal.RobocalError):
                failed += 1
                continue
            kept += bool(np.abs(pin.difference(model, q, drawn[value])).max() < 1e-9)
        print(f"{label:<46}{kept:>4} of {points} on the drawn branch, {points - kept - failed} on the other, "
              f"{failed} not converged")


def timed(fn, repeats: int) -> float:
    """Best CPU time of this process (s) over `repeats` calls: the shared cores' other jobs left out."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    n = args.samples
    robot = robocal.load_urdf(URDF)
    model, loops = robot.model, robot.loops
    geometry = sm.geometry_from_model(robot)
    rng = np.random.default_rng(0)
    R, p = sm.random_workspace_poses(geometry, n, rng)
    struts = sm.inverse_kinematics_batch(geometry, R, p)
    exact = np.array([sm.configuration_from_pose(robot, geometry, pin.SE3(Ri, pi)) for Ri, pi in zip(R, p)])
    nearby = struts + 1e-3
    starts = {"cold": np.tile(pin.neutral(model), (n, 1)),
              "warm": np.array([assemble(robot, model, s) for s in nearby])}

    rows_object = loops.pinocchio_rows(model)
    constraints, datas, views = rows_object.constraints, rows_object.datas, rows_object.views
    data = model.createData()
    passive = loops.solved_v
    ms = ModelState(robot, ParameterSet(), loops.actuated)
    cache: dict = {}      # what a problem keeps between passes (tree and closure structure)
    ClosedChainBatch(ms, struts[:1], {}, jacobian=False, cache=cache)

    print(f"Closed-chain assembly: Stewart 6-6 ({URDF.name}: 6 point closures, 18 rows, 18 passive coordinates), "
          f"{n} samples, stop at max |c| < {TOL:g} m, pin {pin.__version__}, "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}")
    print(f"{'method':<46}{'start':>6}{'us/sample':>11}{'iterations':>12}{'worst |c| m':>13}{'|q - exact|':>13}")
    table = {}
    for start, guesses in starts.items():
        out = {}

        def run_p():
            out["p"] = [pinocchio_projection(model, data, constraints, datas, views, passive,
                                             loops.set_actuated(g, s)) for g, s in zip(guesses, struts)]

        def run_d():
            rows = lambda q: loops.constraint_jacobian(model, data, q)  # noqa: E731
            retract = lambda q, v: pin.integrate(model, q, v)  # noqa: E731
            out["d"] = [damped_newton(rows, loops.set_actuated(g, s), retract, free=passive, tol=TOL,
                                      singular_rcond=1e-5, what="closed-chain assembly")
                        for g, s in zip(guesses, struts)]

        def run_a():
            out["a"] = [assemble(robot, model, s, q_guess=g, data=data) for g, s in zip(guesses, struts)]

        def run_b():
            warm = {i: g for i, g in enumerate(guesses)}
            out["b"] = ClosedChainBatch(ms, struts, warm, jacobian=False, cache=cache).q
        for key, fn in (("p", run_p), ("d", run_d), ("a", run_a), ("b", run_b)):
            table[key, start] = timed(fn, args.repeats) / n * 1e6
        qs = {"p": np.array([q for q, _ in out["p"]]), "d": np.array(out["d"]), "a": np.array(out["a"]),
              "b": out["b"]}
        iters = {"p": np.mean([it for _, it in out["p"]])}
        labels = {"p": "(p) Pinocchio constraint-projected solve", "d": "(d) robocal damped Newton alone",
                  "a": "(a) robocal assemble (projected_assembly)", "b": "(b) robocal batched (calibration)"}
        for key in ("p", "d", "a", "b"):
            worst = max(np.abs(loops.constraint_error(model, data, q)).max() for q in qs[key])
            error = max(np.abs(pin.difference(model, q, e)).max() for q, e in zip(qs[key], exact))
            it = f"{iters[key]:.1f}" if key in iters else "-"
            print(f"{labels[key]:<46}{start:>6}{table[key, start]:>11.1f}{it:>12}{worst:>13.1e}{error:>13.1e}")
    for start in starts:
        p, d, a, b = (table[k, start] for k in "pdab")
        print(f"{start}: (d) / (p) = {d / p:.2f}, (a) / (p) = {a / p:.2f}, (p) / (b) = {p / b:.1f}")
    branch_table()


if __name__ == "__main__":
    main()
