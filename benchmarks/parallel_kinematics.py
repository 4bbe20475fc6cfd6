"""Speed and accuracy of parallel-machine kinematics (Stewart 6-6 and 3-3 of spec seed-000).

Run:  OMP_NUM_THREADS=1 python benchmarks/parallel_kinematics.py [--poses 1000] [--batch 10000]
Prints one table per machine. Times are best of 3 repeats, wall clock, one thread.
Targets (issue 3): closed-form FK single solve < 50 us, batch > 100,000 solves/s.
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
from robocal.model.loops import assemble  # noqa: E402
from robocal.systems.stewart import fk as stewart_fk, mechanism as st  # noqa: E402

URDF = Path(__file__).resolve().parents[1] / "urdf"


def best_of(fn, repeats=3):
    """Best wall time (s) of `repeats` calls of fn()."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def pose_error(a: pin.SE3, b: pin.SE3) -> float:
    return float(np.linalg.norm(pin.log6(a.actInv(b)).vector))


def run(name: str, geometry: st.StewartGeometry, n_poses: int, n_batch: int, rng) -> list[tuple[str, str, str]]:
    robot = robocal.load_urdf(URDF / f"stewart_{name}.urdf")
    model, data = robot.model, robot.model.createData()
    rows = []

    # accuracy: closed-form round trip (200) and generic FK vs closed-form IK (n_poses)
    R, p = st.random_workspace_poses(geometry, max(n_poses, 200), rng)
    s = st.inverse_kinematics_batch(geometry, R, p)
    poses = [pin.SE3(R[k], p[k]) for k in range(len(R))]
    worst = max(pose_error(stewart_fk.forward_kinematics(geometry, s[k]), poses[k]) for k in range(200))
    rows.append(("IK/FK round trip, 200 poses, max |log6|", f"{worst:.2e}", "< 1e-9"))
    worst, q = 0.0, None
    for k in range(n_poses):
        q = assemble(robot, model, s[k], q_guess=q, sample=k, data=data)
        worst = max(worst, pose_error(st.platform_pose(robot, model, q, data), poses[k]))
    rows.append((f"generic FK vs closed-form IK, {n_poses} poses", f"{worst:.2e}", "< 1e-10"))

    # single solves: cold = from the home pose, warm = from a pose 1 mm / 1 mrad away
    n = 200
    near = [poses[k] * pin.exp6(np.full(6, 1e-3)) for k in range(n)]
    t = best_of(lambda: [stewart_fk.forward_kinematics(geometry, s[k]) for k in range(n)]) / n
    rows.append(("closed-form FK single solve, cold start", f"{t * 1e6:.1f} us", "< 50 us"))
    t = best_of(lambda: [stewart_fk.forward_kinematics(geometry, s[k], guess=near[k]) for k in range(n)]) / n
    rows.append(("closed-form FK single solve, warm start", f"{t * 1e6:.1f} us", "< 50 us"))
    t = best_of(lambda: [st.inverse_kinematics(geometry, poses[k]) for k in range(n)]) / n
    rows.append(("closed-form IK single pose", f"{t * 1e6:.1f} us", ""))
    m = 50
    t = best_of(lambda: [assemble(robot, model, s[k], sample=k, data=data) for k in range(m)], 1) / m
    rows.append(("generic (Pinocchio) FK, cold start", f"{t * 1e3:.2f} ms", ""))
    warm_q = [st.configuration_from_pose(robot, geometry, near[k]) for k in range(m)]
    t = best_of(lambda: [assemble(robot, model, s[k], q_guess=warm_q[k], data=data) for k in range(m)], 1) / m
    rows.append(("generic (Pinocchio) FK, warm start", f"{t * 1e3:.2f} ms", ""))

    # batches
    Rb, pb = st.random_workspace_poses(geometry, n_batch, rng)
    sb = st.inverse_kinematics_batch(geometry, Rb, pb)
    t = best_of(lambda: stewart_fk.forward_kinematics_batch(geometry, sb))
    Rf, pf, converged = stewart_fk.forward_kinematics_batch(geometry, sb)
    err = max(np.abs(Rf - Rb).max(), np.abs(pf - pb).max())
    rows.append((f"closed-form FK batch of {n_batch}, cold start", f"{n_batch / t:,.0f} /s", "> 100,000 /s"))
    rows.append(("  batch converged / max error", f"{converged.sum()}/{n_batch}, {err:.1e}", ""))
    t = best_of(lambda: stewart_fk.forward_kinematics_batch(geometry, sb, Rb @ st.rotation_xyz([1e-3] * 3), pb + 1e-3))
    rows.append((f"closed-form FK batch of {n_batch}, warm start", f"{n_batch / t:,.0f} /s", "> 100,000 /s"))
    t = best_of(lambda: st.inverse_kinematics_batch(geometry, Rb, pb))
    rows.append((f"closed-form IK batch of {n_batch}", f"{n_batch / t:,.0f} /s", ""))
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=1000, help="poses for the generic-vs-closed-form check")
    parser.add_argument("--batch", type=int, default=10000, help="batch size for throughput")
    args = parser.parse_args()
    rng = np.random.default_rng(2024)
    for name, geometry in (("6_6", st.StewartGeometry.spec_6_6()), ("3_3", st.StewartGeometry.spec_3_3())):
        rows = run(name, geometry, args.poses, args.batch, rng)
        width = max(len(r[0]) for r in rows)
        print(f"\nStewart {name.replace('_', '-')} (spec seed-000 geometry), pin {pin.__version__}, "
              f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}")
        print(f"{'quantity':<{width}}  {'value':>22}  target")
        print("-" * (width + 40))
        for label, value, target in rows:
            print(f"{label:<{width}}  {value:>22}  {target}")


if __name__ == "__main__":
    main()
