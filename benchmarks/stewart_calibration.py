"""Speed and accuracy of Stewart-platform calibration (spec seed-000), generic closed-loop path.

Run:  OMP_NUM_THREADS=1 python benchmarks/stewart_calibration.py [--poses 50] [--repeats 3]
          [--workers N | --scheduler ADDR] [--instruments [--machines 15]]
Prints one table: 42-parameter fit from full poses (target < 1 s on one core), the two-stage solve from
300 mm errors, and a mixed-mode fit. With --instruments, also what each instrument's error costs
(docs/stewart_calibration.md): modes 4 and 5 at 60 and 300 contacts with the CMM's error on T at 0, 2, 5,
10 um (T carried as priors of that size; 0: T at the truth) and the strut noise at 0, 0.1, 1 um; the
largest tip error over 50 validation poses, median (worst) of the machines (about 4 min of one core). Times are best of `repeats`, wall clock, one thread; repeat k is a
machine drawn from the k-th child seed of SeedSequence(0), so --workers/--scheduler (Dask, one thread per
worker) fit the same machines, each timed on the worker that fits it.
"""
from __future__ import annotations

import argparse
import os
import time
from functools import lru_cache, partial
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import robocal  # noqa: E402
from robocal.systems.stewart import calibration as sc, modes as sm  # noqa: E402
from robocal.estimation.calibrate import calibrate  # noqa: E402
from robocal.estimation.problem import Problem  # noqa: E402
from robocal.testing import monte_carlo  # noqa: E402
from robocal.systems.stewart import fit_machines  # noqa: E402
from robocal.systems.stewart.two_stage import calibrate_two_stage  # noqa: E402

URDF = Path(__file__).resolve().parents[1] / "urdf" / "stewart_6_6.urdf"
TOOL = sm.Tool(0.2, 0.003)


@lru_cache(maxsize=1)
def stewart():
    """Loaded once per process: a Dask worker loads its own (Pinocchio's loop closures do not pickle)."""
    return robocal.load_urdf(URDF)


def case(n, sigma, two_stage, rng):
    robot = stewart()
    truth = sc.stewart_parameters()
    for p in truth:
        p.value = rng.normal(0, sigma)
    tips = sc.random_tips(n, rng)
    abc, R = sc.random_orientations(n, rng)
    s = sc.struts(sc.geometry(robot, truth), sc.tip_to_platform(tips, R, TOOL))
    rows = np.column_stack([tips, abc])
    params = sc.stewart_parameters()
    problem = Problem(robot, params, sc.actuated(robot), s,
                      sm.pose_residuals("pose", robot, np.arange(n), rows, [1, 1, 1, 1, 1, 1], TOOL,
                                        (1e-6, 1e-6)))
    t0 = time.perf_counter()
    result = calibrate_two_stage(problem, np.arange(n), rows, TOOL)[1] if two_stage else calibrate(problem)
    dt = time.perf_counter() - t0
    err = max(abs(params[p.name].value - p.value) for p in truth)
    return dt, result.solve.nit, err


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--poses", type=int, default=50)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, help="repeats on a LocalCluster of N processes (Dask)")
    ap.add_argument("--scheduler", help="repeats on the Dask scheduler at ADDR (tcp://host:8786)")
    ap.add_argument("--instruments", action="store_true", help="also what each instrument's error costs")
    ap.add_argument("--machines", type=int, default=15, help="simulated machines per cell of --instruments")
    args = ap.parse_args()
    rows = []
    for label, sigma, two in (("FK fit, 1 mm errors", 1e-3, False), ("two-stage, 300 mm errors", 0.3, True)):
        runs = monte_carlo(partial(case, args.poses, sigma, two), args.repeats, seed=0,
                           scheduler=args.scheduler, workers=args.workers)
        best = min(r[0] for r in runs)
        rows.append((label, args.poses, best, max(r[1] for r in runs), max(r[2] for r in runs)))
    print(f"{'case':<28}{'poses':>6}{'best time (s)':>15}{'iterations':>12}{'max param error (m)':>22}")
    for label, n, t, it, err in rows:
        print(f"{label:<28}{n:>6}{t:>15.3f}{it:>12}{err:>22.2e}")
    if args.instruments:
        instruments(args.machines, dict(scheduler=args.scheduler, workers=args.workers))


def instruments(machines: int, engine: dict):
    """Modes 4 and 5 at 60 and 300 contacts, one instrument's error varied at a time (the others as stated)."""
    cells = [("mode 4, 60", "balls", 60), ("mode 4, 300", "balls", 300), ("mode 5, 60", "ball_bar", 60),
             ("mode 5, 300", "ball_bar", 300)]
    rows = [(f"CMM {c * 1e6:g} um, struts 1 um", dict(sig_cmm=c or 5e-6, sig_s=1e-6), "true" if c == 0 else "cmm_prior")
            for c in (0.0, 2e-6, 5e-6, 10e-6)]
    rows += [(f"CMM 5 um, struts {s * 1e6:g} um", dict(sig_cmm=5e-6, sig_s=s), "cmm_prior") for s in (0.0, 1e-7)]
    print(f"\nmax tip error over 50 validation poses (um), median (worst) of {machines} machines "
          "(CMM 0 um: T at the truth)")
    print(f"{'instruments':<30}" + "".join(f"{label:>22}" for label, _, _ in cells))
    for label, options, pj in rows:
        out = []
        for _, mode, n in cells:
            fits = fit_machines(stewart(), TOOL, lambda s, mode=mode, n=n: getattr(s, mode)(n), pj, machines, seed=0,
                                **engine, **options)
            tips = np.array([f[0] for f in fits]) * 1e6
            out.append(f"{np.median(tips):.2f} ({tips.max():.2f})")
        print(f"{label:<30}" + "".join(f"{o:>22}" for o in out))


if __name__ == "__main__":
    main()
