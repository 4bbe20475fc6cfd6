"""Speed and accuracy of the floating-nut hexapod kinematics (one core). Prints three tables.

Run: OMP_NUM_THREADS=1 python benchmarks/floating_nut_kinematics.py [--baseline-commit 215e72e]
Targets (issue 5): compensated IK > 200,000 poses/s in batch; FK < 50 us per solve.
The first table times the numpy FK of --baseline-commit (its fk.py and kinematics.py read with `git show` into
temporary modules; the commit must be in this repository's history) against the current numpy FK on the same
lengths, with the largest pose difference between the two. Rows marked (numba) use the optional compiled
single-pose FK (pip install robocal[fast]); the other rows force numpy.
"""
import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

from git_baseline import module_at_commit  # noqa: E402
from robocal.systems.floating_nut.geometry import reference_fixture  # noqa: E402
from robocal.systems.floating_nut.kinematics import FloatingNutKinematics  # noqa: E402

DEG = np.pi / 180


def baseline_kinematics(commit):
    """FloatingNutKinematics of `commit` with its own numpy single-pose solver (numba off)."""
    old_fk = module_at_commit(commit, "robocal/systems/floating_nut/fk.py", "baseline_fk")
    old = module_at_commit(commit, "robocal/systems/floating_nut/kinematics.py", "baseline_kinematics")
    kin = old.FloatingNutKinematics(reference_fixture(), use_numba=False)
    kin._single = old_fk.SinglePoseFK(kin)     # not the current solver its import of fk_compiled would give
    return kin


def comparison_rows(old, new):
    """(operation, baseline us, current us, max |pose difference|) for the numpy FK paths."""
    rows = []
    P = poses(new, 200)
    lc = new.ik(P)
    cases = [("FK single call, cold (full J)", lambda k: [k.fk(l) for l in lc], 200),
             ("FK single call, cold (uncompensated J)", lambda k: [k.fk(l, jacobian="uncompensated") for l in lc], 200),
             ("FK single call, warm (1e-4 step)",
              lambda k: [k.fk(l, p_init=p + 1e-4, warn_condition=None) for l, p in zip(lc, P)], 200)]
    for n in (1_000, 10_000):
        Pn = poses(new, n)
        ln = new.ik(Pn)
        cases.append((f"FK batch {n}, cold (full J)", lambda k, ln=ln: [k.fk(ln)], n))
        cases.append((f"FK batch {n}, warm (1e-4 step)", lambda k, ln=ln, Pn=Pn: [k.fk(ln, p_init=Pn + 1e-4)], n))
    for name, run, n in cases:
        t_old = best_time(lambda: run(old), repeat=5)
        t_new = best_time(lambda: run(new), repeat=5)
        a = np.array([r.pose for r in run(old)]).reshape(-1, 6)
        b = np.array([r.pose for r in run(new)]).reshape(-1, 6)
        rows.append((name, t_old / n * 1e6, t_new / n * 1e6, np.abs(a - b).max()))
    return rows


def poses(kin, n, seed=0):
    rng = np.random.default_rng(seed)
    return kin.geometry.p0 + np.hstack([rng.uniform(-0.1, 0.1, (n, 3)), rng.uniform(-10, 10, (n, 3)) * DEG])


def best_time(fn, repeat=5):
    """Best wall time of `repeat` runs, s (the least disturbed by the other users of the machine)."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def speed_rows(kin, kin_numba=None):
    """kin: numpy single-pose FK (use_numba=False); kin_numba: the numba kernel, rows skipped if None."""
    rows = []
    for n in (1_000, 100_000):
        P = poses(kin, n)
        t = best_time(lambda: kin.ik(P))
        rows.append((f"IK compensated, batch {n}", n / t, t / n * 1e6, "target > 200k/s"))
        t = best_time(lambda: kin.ik(P, compensate=False))
        rows.append((f"IK uncompensated, batch {n}", n / t, t / n * 1e6, ""))
    P = poses(kin, 10_000)
    t = best_time(lambda: kin.jacobian(P))
    rows.append(("Jacobian J_c, batch 10000", 1e4 / t, t / 1e4 * 1e6, ""))
    for n in (1_000, 10_000):
        P = poses(kin, n)
        lc = kin.ik(P)
        for mode in ("full", "uncompensated"):
            t = best_time(lambda: kin.fk(lc, jacobian=mode), repeat=3)
            rows.append((f"FK cold ({mode} J), batch {n}", n / t, t / n * 1e6, "target < 50 us"))
        t = best_time(lambda: kin.fk(lc, p_init=P + 1e-4), repeat=3)
        rows.append((f"FK warm (1e-4 step), batch {n}", n / t, t / n * 1e6, ""))
    P = poses(kin, 200)
    lc = kin.ik(P)
    t = best_time(lambda: [kin.ik(p) for p in P], repeat=3)
    rows.append(("IK single call", 200 / t, t / 200 * 1e6, "numpy call overhead"))
    # one pose per call goes through the lean single-pose solver: numpy (floating_nut_fk.py), then numba
    for solver, tag in ((kin, ""), (kin_numba, ", numba")):
        if solver is None:
            continue
        solver.fk(lc[0])                        # compile, or load numba's cache, before timing
        t = best_time(lambda: [solver.fk(l) for l in lc], repeat=5)
        rows.append((f"FK single call, cold{' (numba)' if tag else ''}", 200 / t, t / 200 * 1e6, "target < 50 us"))
        t = best_time(lambda: [solver.fk(l, jacobian="uncompensated") for l in lc], repeat=5)
        rows.append((f"FK single call, cold (uncompensated J{tag})", 200 / t, t / 200 * 1e6, ""))
        t = best_time(lambda: [solver.fk(l, p_init=p + 1e-4, warn_condition=None) for l, p in zip(lc, P)],
                      repeat=5)
        rows.append((f"FK single call, warm{' (numba)' if tag else ''}", 200 / t, t / 200 * 1e6, ""))
    return rows


def accuracy_rows(kin):
    P = poses(kin, 10_000, seed=1)
    lc, d = kin.ik(P, return_details=True)
    full = kin.fk(lc)
    quasi = kin.fk(lc, jacobian="uncompensated")
    wrong = kin.fk(lc, compensate=False).pose - P
    pos_err = np.linalg.norm(wrong[:, :3], axis=1)
    return [
        ("max |theta| over the box [deg]", np.abs(d.theta).max() / DEG),
        ("mean per-pose max |theta| [deg]", np.abs(d.theta).max(axis=1).mean() / DEG),
        ("max |l_a| [um]", np.abs(d.additional).max() * 1e6),
        ("uncompensated FK position error, max [um]", pos_err.max() * 1e6),
        ("uncompensated FK position error, mean [um]", pos_err.mean() * 1e6),
        ("uncompensated FK angle error, max [mdeg]", np.abs(wrong[:, 3:]).max() / DEG * 1e3),
        ("FK round trip, max pose error", np.abs(full.pose - P).max()),
        ("FK iterations full J: mean / max", f"{full.iterations.mean():.2f} / {full.iterations.max()}"),
        ("FK iterations J_l only: mean / max", f"{quasi.iterations.mean():.2f} / {quasi.iterations.max()}"),
        ("cond(J_c) at home", np.linalg.cond(kin.jacobian(kin.geometry.p0))),
    ]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--baseline-commit", default="215e72e",
                    help="commit whose numpy FK is timed as the baseline ('' to skip)")
    a = ap.parse_args()
    kin = FloatingNutKinematics(reference_fixture(), use_numba=False)   # numpy rows
    if a.baseline_commit:
        print(f"numpy FK, baseline ({a.baseline_commit}) against current, us per pose, best of 5, one core")
        print(f"{'operation':40s} {'baseline':>9s} {'current':>9s} {'speed-up':>9s}  max |pose difference|")
        for name, t_old, t_new, diff in comparison_rows(baseline_kinematics(a.baseline_commit), kin):
            print(f"{name:40s} {t_old:9.2f} {t_new:9.2f} {t_old / t_new:9.2f}  {diff:.1e}")
        print()
    try:
        kin_numba = FloatingNutKinematics(reference_fixture(), use_numba=True)
        kin_numba._single_pose_solver()
    except ImportError:
        kin_numba = None                        # numba not installed: no numba rows
    print("floating-nut hexapod kinematics, reference fixture (docs/floating_nut_hexapod.md), box +-0.1 m / +-10 deg, one core")
    print(f"{'operation':46s} {'per second':>14s} {'us each':>10s}  note")
    for name, rate, us, note in speed_rows(kin, kin_numba):
        print(f"{name:46s} {rate:14,.0f} {us:10.2f}  {note}")
    if kin_numba is None:
        print("(numba not installed: pip install robocal[fast] for the compiled single-pose FK)")
    print()
    print(f"{'accuracy over 10,000 random poses':45s} value")
    for name, value in accuracy_rows(kin):
        print(f"{name:45s} {value if isinstance(value, str) else f'{value:.4g}'}")


if __name__ == "__main__":
    main()
