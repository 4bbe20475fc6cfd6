"""Benchmark: external-force estimation over a 45,000-sample 6-axis log, and one 4 ms control tick.

Run with OMP_NUM_THREADS=1 (threaded BLAS is much slower on these small matrices):
    OMP_NUM_THREADS=1 python benchmarks/external_force.py
Targets: > 100,000 samples/s for the batch; < 0.2 ms for a tick (estimate + generator + IK).
"""
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import robocal  # noqa: E402
from robocal.dynamics import (ActuatorModel, ExternalForceEstimator, FrictionModel, MotionParams,  # noqa: E402
                              PathGenerator, TickDifferentiator, differentiate, movejf, movelf)

Q0 = np.array([0.3, -1.2, 1.5, -1.9, -1.5, 0.2])


def best_of(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times), float(np.median(times))


def main():
    robot = robocal.load_example("ur5")
    m, fid = robot.model, robot.frame_id("tool0")
    act = ActuatorModel([0.12, 0.12, 0.11, 0.09, 0.09, 0.08], [101] * 6, [0.01] * 6)
    fr = FrictionModel([3, 3, 2, 1, 1, 0.8], [5, 5, 3, 1, 1, 1], smoothing=0.01)
    est = ExternalForceEstimator(m, fid, act, fr)
    n, dt = 45_000, 0.004
    t = np.arange(n) * dt
    q = Q0 + 0.3 * np.sin(2 * np.pi * 0.5 * t[:, None] + np.arange(6))
    rng = np.random.default_rng(0)
    cur = rng.normal(size=(n, 6))
    v, a = differentiate(q, dt)
    rows = []
    lo, med = best_of(lambda: differentiate(q, dt), 5)
    rows.append(("differentiate (central), 45k x 6", lo, med, n / lo))
    lo, med = best_of(lambda: est.estimate(q, v, a, cur), 3)
    rows.append(("estimate wrench (rnea+J+damped map), 45k", lo, med, n / lo))
    lo, med = best_of(lambda: (differentiate(q, dt), est.estimate(q, v, a, cur)), 3)
    rows.append(("differentiate + estimate, 45k", lo, med, n / lo))

    # one control tick: differentiator + estimator tick + generator (limits, regulator, IK)
    d = m.createData()
    pin.framesForwardKinematics(m, d, Q0)
    start = d.oMf[fid].copy()
    params = MotionParams(0.25, 1.0, admittance=0.002)
    lin = movelf(m, fid, Q0, pin.SE3(start.rotation, start.translation + [0.2, 0, 0]), params, 10.0)
    jnt = movejf(m, fid, Q0, Q0 + 0.3, params, 10.0)
    for label, ins in (("tick: MOVELF (estimate + generator + IK)", lin), ("tick: MOVEJF (estimate + generator)", jnt)):
        gen = PathGenerator(m, ins)
        diff = TickDifferentiator(dt)
        ticks = 500
        state = {"k": 0}

        def run():
            for _ in range(ticks):
                k = state["k"] % n
                st = diff.push(q[k])
                w = est.tick(*st, cur[k])[0] if st is not None else np.zeros(6)
                gen.tick(w * 1e-3)
                state["k"] += 1
        lo, med = best_of(run, 3)
        rows.append((label, lo / ticks, med / ticks, ticks / lo))

    print(f"{'operation':46s} {'best [ms]':>10s} {'median [ms]':>12s} {'rate [/s]':>12s}")
    for name, lo, med, rate in rows:
        print(f"{name:46s} {lo * 1e3:10.3f} {med * 1e3:12.3f} {rate:12,.0f}")


if __name__ == "__main__":
    main()
