"""Benchmark: dynamic identification of the shipped TIAGo log through its config alone.

    OMP_NUM_THREADS=1 python benchmarks/dynamics_tiago.py [--repeats N] [--figaroh]

Prints the held-out torque RMSE per recorded joint for the CAD model (the baseline, same run), the
OLS base parameters and the physically consistent model, the free-motion external force, and the
wall time of the whole identification (best and median of N runs). --figaroh would run FIGAROH in
its own virtual environment on the same training window: not implemented yet (see
docs/dynamics_tiago.md), the flag says so and the script goes on without it.
"""
import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from robocal.dynamics.identify_run import MODELS, identify_from_config  # noqa: E402

CONFIG = Path(__file__).resolve().parents[1] / "examples/tiago_dynamics/identify.yaml"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--figaroh", action="store_true", help="also run FIGAROH (not implemented: prints a notice)")
    args = ap.parse_args(argv)
    times, cpu, res = [], [], None
    for _ in range(args.repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        res = identify_from_config(CONFIG)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    units = ["N" if res.model.joints[res.model.getJointId(j)].shortname().startswith("JointModelP") else "N m"
             for j in res.recorded]
    print(f"config: {CONFIG}")
    print(f"train {list(res.config.train)} s ({res.train.sum()} samples), validate {list(res.config.validate)} s "
          f"({res.check.sum()} samples); cut-off {res.processed.cutoff_hz:.3g} Hz, "
          f"decimation {res.processed.decimation}")
    print(f"OLS: {res.ols.selection.rank} base parameters, condition {res.ols.condition:.4g}; consistent: prior weight "
          f"{res.consistent.prior_weight:g} (grid scores " + ", ".join(f"{s:.3f}" for s in res.prior.scores)
          + f"), ADMM {res.consistent.iterations} iterations, converged {res.consistent.converged}")
    print("\nheld-out torque RMSE (% of range)")
    print("| model | " + " | ".join(f"{j} ({u})" for j, u in zip(res.recorded, units)) + " |")
    print("|---" * (len(res.recorded) + 1) + "|")
    for m in MODELS:
        v = res.validation[m]
        cells = [f"{r:.3f} ({p:.1f} %)" for r, p in zip(v["rmse"], v["percent_of_range"])]
        print(f"| {m} | " + " | ".join(cells) + " |")
    ratio = np.array(res.validation["consistent"]["rmse"]) / np.array(res.validation["ols"]["rmse"])
    print("| consistent / ols | " + " | ".join(f"{r:.3f}" for r in ratio) + " |")
    print(f"\nexternal force at {res.wrench_rms['frame']}, validation window, RMS per world axis (N)")
    print("| model | fx | fy | fz |\n|---|---|---|---|")
    for m in MODELS:
        print(f"| {m} | " + " | ".join(f"{f:.3f}" for f in res.wrench_rms[m]) + " |")
    wn = res.within_noise
    print(f"\nconsistent vs OLS on the training window: residual increase "
          f"{wn['residual_increase_in_noise_units']:.1f} noise units (chi-square 95 %: {wn['chi2_95']:.1f}); "
          "RMS ratio " + ", ".join(f"{r:.3f}" for r in wn["rms_ratio"]))
    print(f"\nidentification wall time (load, filter, OLS, prior-weight grid, consistent fit, validation): "
          f"best {min(times):.2f} s, median {np.median(times):.2f} s over {len(times)} run(s); "
          f"CPU time best {min(cpu):.2f} s (the machine may be shared)")
    if args.figaroh:
        print("\nFIGAROH: not implemented in this script yet (it would install PyPI `figaroh` in its own "
              "virtual environment); skipped.")


if __name__ == "__main__":
    main()
