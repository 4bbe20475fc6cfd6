"""Calibrate a 6-6 Stewart platform in each of the five measuring modes on its own, then in a mix.

Source: Chinese patent application CN1951642A, "Parallel kinematic machine, calibration method of the
parallel kinematic machine, and calibration program product" (docs/stewart_calibration.md). The true
machine is the nominal one with N(0, 1 mm) on every one of its 42 parameters; measurements carry the
spec's noise (1 um on positions, contact distances and ball-bar readings, 1 urad on angles). Each fit is
judged like the spec's headline: the largest tool-tip error over 50 fresh validation poses. Modes 2-5
measure the tip's position only, so alone they cannot see the platform joints T turn about the tip: as
in the patent, T is then measured beforehand (fixed at its true value) and 24 parameters are fitted.
Every row is repeated on DRAWS simulated machines (median and worst shown; about 5 min of one core),
machine k drawn from the k-th child seed of SeedSequence(0): the same figures serially and on Dask.
Prints the markdown table
(spec figure / robocal figure / how computed) of the docs page. Run:
    OMP_NUM_THREADS=1 python examples/stewart_calibration.py [--workers N | --scheduler ADDR]
"""
import argparse
from pathlib import Path

import numpy as np

import robocal
from robocal.systems.stewart import modes as sm
from robocal.systems.stewart import BALLS, BAR_BASES, HOLES, PLANES, ModeStudy, fit_machines, mix

DRAWS = 15     # a median over 5 machines moved with the draw (mode 2: 1.51x or 2.16x of the spec)
N_CONTACTS = 100                          # contacts per reference object (modes 2-5)
HEADLINE = {12: 4.0, 30: 1.5, 60: 1.3}    # spec: max tip error (um) after a mode-1 fit on n poses

robot = robocal.load_urdf(Path(__file__).resolve().parents[1] / "urdf" / "stewart_6_6.urdf")
tool = sm.Tool(length=0.2, tip_radius=0.003)


def mixed(study: ModeStudy):
    """12 full poses, then one plane, one hole, one ball and one ball-bar place, all 42 parameters free."""
    parts = [study.full_poses(12)]
    for make, objects in ((study.planes, PLANES[:1]), (study.holes, HOLES[:1]), (study.balls, BALLS[:1]),
                          (study.ball_bar, BAR_BASES[:1])):
        parts.append(make(N_CONTACTS, first=sum(len(p.struts) for p in parts), objects=objects))
    return mix(parts)


def contact_row(mode, what, make, objects):
    per = N_CONTACTS
    n = per * len(objects)
    return (f"mode {mode}, {len(objects)} {what} x {per} contacts, T fixed, 24 free",
            lambda s: make(s, per), True, HEADLINE[30],
            f"spec has no figure for this mode: its 30-pose mode-1 figure (180 numbers; here {n})")


ROWS = [  # label, data set, T fixed, spec figure (um), how the spec figure relates
    *[(f"mode 1, full poses, {n} poses, 42 free", lambda s, n=n: s.full_poses(n), False, HEADLINE[n],
       "spec: mode 1 on the same number of poses") for n in (12, 30, 60)],
    contact_row(2, "planes", ModeStudy.planes, PLANES),
    contact_row(3, "holes", ModeStudy.holes, HOLES),
    contact_row(4, "balls", ModeStudy.balls, BALLS),
    contact_row(5, "ball-bar places", ModeStudy.ball_bar, BAR_BASES),
    (f"mix: 12 poses + 1 plane + 1 hole + 1 ball + 1 ball bar ({N_CONTACTS} each), 42 free", mixed, False,
     HEADLINE[12], "spec: mode 1 on its 12 poses (the contacts come on top)"),
]

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, help="spread the machines over a LocalCluster of N processes (Dask)")
    ap.add_argument("--scheduler", help="spread the machines over the Dask scheduler at ADDR (tcp://host:8786)")
    args = ap.parse_args()
    if args.workers and not args.scheduler:
        # one LocalCluster for all rows (fit_machines(workers=N) would start one per row); the [fleet] extra
        from dask.distributed import LocalCluster
        with LocalCluster(n_workers=args.workers, threads_per_worker=1, dashboard_address=":0",
                          env={"OMP_NUM_THREADS": "1"}) as cluster:
            print_table(cluster.scheduler_address)
    else:
        print_table(args.scheduler)


def print_table(scheduler):
    engine = dict(scheduler=scheduler)
    # machine k (true parameters, validation poses) is the same in every row; each row draws its data afresh
    before = [tip for tip, _ in fit_machines(robot, tool, None, False, DRAWS, seed=0, **engine)]
    print(f"tool-tip error before calibration: {np.median(before) * 1e3:.2f} mm median of {DRAWS} machines "
          f"(max over 50 validation poses; spec: 7 mm)\n")
    table = []
    for label, make, fix_t, spec, how in ROWS:
        fits = fit_machines(robot, tool, make, fix_t, DRAWS, seed=0, **engine)
        tips, ranks = [tip * 1e6 for tip, _ in fits], {rank for _, rank in fits}
        med, worst = float(np.median(tips)), max(tips)
        print(f"{label:<80} rank {'/'.join(map(str, sorted(ranks))):>5}  tip error median {med:5.2f} um, worst "
              f"{worst:5.2f} um  (spec {spec} um: {med / spec:.2f}x)")
        table.append(f"| {label} | {spec} | {med:.2f} (worst {worst:.2f}) | max over 50 fresh poses, median of "
                     f"{DRAWS} simulated machines; {how} |")
    print("\n| data (1 um / 1 urad noise) | spec figure: max tip error (um) | robocal figure (um) | how computed |")
    print("|---|---|---|---|")
    print("\n".join(table))
    print(f"| before calibration | 7000 | {np.median(before) * 1e6:.0f} | same validation poses, nominal model |")


if __name__ == "__main__":   # Dask starts its worker processes by importing this file again
    main()
