"""Motor-side identification from 5 kHz logs (docs/dynamics_motors.md): memory and time of reading and reducing a
log, and the synthetic truth over several seeds.

    OMP_NUM_THREADS=1 python benchmarks/dynamics_motor_logs.py --memory      # peak memory against the log length
    OMP_NUM_THREADS=1 python benchmarks/dynamics_motor_logs.py --seeds 5     # both examples, seeds 0..4
    OMP_NUM_THREADS=1 python benchmarks/dynamics_motor_logs.py --monte-carlo 16 --case ur5_coupled --seed 3 \
        [--cutoff-margin 3]                                                 # noise draws on one robot

--memory: the UR5 example's log written at 20, 60 and 120 s (100k, 300k, 600k rows of 12 columns), then read
by robocal's motor-log reader (blocks of 8192 rows, reduced to 250 Hz on the way) and, as the baseline in the
same run, by the whole-file table reader the joint-log path uses (robocal.io.tables.read_csv, every cell as
text, then the 12 columns as floats); peak Python allocations by tracemalloc, wall time by perf_counter in a
second, untraced call.
--seeds: each example's logs made with seeds 0..n-1 (robot truth, trajectory and noise all change) and
identified from its config: the base parameters' sum of squared z against chi-square(rank) and the largest |z|,
the motors' friction and rotor inertias the same way, and `robocal evaluate`'s per-motor RMSE on session 2 in
units of the current noise.
--monte-carlo N: one example's robot and trajectories (--case, --seed) with N noise draws: the reported standard
errors against the spread of the estimates, and the estimates' mean against the truth in standard errors of that
mean (a bias the noise does not explain); --cutoff-margin overrides signal.cutoff_margin.
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import yaml
from scipy.stats import chi2

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from motor_dynamics_cases import CASES, base_z, make_logs, true_parameters, write_case  # noqa: E402
from robocal.dynamics.identification import base_values_of  # noqa: E402
from robocal.dynamics.motor_log import load_motor_log  # noqa: E402
from robocal.io.tables import read_csv  # noqa: E402
from robocal.workflows.identify import identify_from_config  # noqa: E402
from robocal.workflows.identify_evaluate import evaluate_dynamics  # noqa: E402
from robocal.workflows.identify_outputs import write_identification  # noqa: E402


def peak(function):
    """(result, peak traced allocation MB, wall time s of a second call without tracing: tracemalloc slows
    allocation-heavy code several times)."""
    tracemalloc.start()
    out = function()
    _, top = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    start = time.perf_counter()
    function()
    return out, top / 1e6, time.perf_counter() - start


def memory_table(folder: Path) -> None:
    motors = [f"motor_{i}" for i in range(1, 7)]
    patterns = {"position": "{motor}_position", "effort": "{motor}_current"}
    print("| log | rows | file (MB) | float64 data (MB) | motor-log reader: peak (MB), time (s) | "
          "whole-file table: peak (MB), time (s) |")
    print("|---|---|---|---|---|---|")
    for seconds in (20.0, 60.0, 120.0):
        config, _ = write_case("ur5_coupled", folder / f"{seconds:g}", seconds=seconds)
        log = config.parent / "data" / "ur5_coupled_session1.csv"
        files = {"position": log, "effort": log}
        reduced, mb, s = peak(lambda: load_motor_log(files, motors, motors, None, 2e-4, patterns, 250.0))
        rows = int(round(seconds * 5000))

        def whole():
            table = read_csv(log)
            return np.column_stack([table.column(n) for n in table.header])

        _, mb_base, s_base = peak(whole)
        print(f"| {seconds:g} s at 5 kHz | {rows} | {log.stat().st_size / 1e6:.1f} | {rows * 12 * 8 / 1e6:.1f} | "
              f"{mb:.1f}, {s:.2f} ({len(reduced.t)} rows kept) | {mb_base:.1f}, {s_base:.2f} |")
        shutil.rmtree(folder / f"{seconds:g}")


def seeds_table(folder: Path, n: int) -> None:
    noise = make_logs().CURRENT_NOISE
    print("| example | seed | base parameters | sum z^2 (chi2 99.9 %) | max abs z | motor terms alone: max abs z | "
          "merged rotor inertias | evaluate RMSE / noise, per motor (max) | identify (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for case in CASES:
        for seed in range(n):
            sub = folder / f"{case}_{seed}"
            config, truth = write_case_seed(case, sub, seed)
            start = time.perf_counter()
            res = identify_from_config(config)
            took = time.perf_counter() - start
            z = base_z(res, truth)
            motor = [abs(zz) for name, zz in zip(res.ols.names, z) if name.split(".")[0] in res.recorded]
            merged = [f"{m}.armature" for m in res.recorded if f"{m}.armature" not in res.ols.names]
            write_identification(res, sub / "out")
            ev = evaluate_dynamics(sub / "out", config.parent / f"{case}_session2.yaml")
            ratio = ev.rmse_logged / (noise * truth.config.transmission.motor_constant)
            rank = res.ols.selection.rank
            print(f"| {case} | {seed} | {rank} | {np.sum(z ** 2):.1f} ({chi2.ppf(0.999, rank):.1f}) | "
                  f"{np.abs(z).max():.2f} | {max(motor):.2f} | {', '.join(merged) or 'none'} | {ratio.max():.3f} | "
                  f"{took:.2f} |")
            shutil.rmtree(sub)


def write_case_seed(case: str, folder: Path, seed: int, noise_seed: int | None = None, margin: float | None = None):
    """write_case with another seed (motor_dynamics_cases writes seed 0), optionally another noise draw and
    cut-off margin."""
    folder.mkdir(parents=True, exist_ok=True)
    for yaml_file in (ROOT / "examples" / "motor_dynamics").glob(f"{case}*.yaml"):
        shutil.copyfile(yaml_file, folder / yaml_file.name)
    if margin is not None:
        cfg = yaml.safe_load((folder / f"{case}.yaml").read_text())
        cfg["signal"]["cutoff_margin"] = margin
        (folder / f"{case}.yaml").write_text(yaml.safe_dump(cfg))
    truth = make_logs().write_case(case, folder / "data", seed=seed, config=folder / f"{case}.yaml",
                                   noise_seed=noise_seed)
    return folder / f"{case}.yaml", truth


def monte_carlo(folder: Path, case: str, seed: int, draws: int, margin: float | None) -> None:
    values, stds = [], []
    for k in range(draws):
        config, truth = write_case_seed(case, folder / "mc", seed, 1000 + 7 * k, margin)
        res = identify_from_config(config)
        values.append(res.ols.values)
        stds.append(res.ols.std)
        beta = base_values_of(res.ols.selection, true_parameters(res, truth))
    values, stds = np.array(values), np.array(stds)
    spread = values.std(axis=0, ddof=1)
    ratio = spread / stds.mean(axis=0)
    bias = (values.mean(axis=0) - beta) / spread
    z2 = np.sum(((values - beta) / stds) ** 2, axis=1)
    print(f"{case}, seed {seed}, {draws} noise draws, cutoff_margin {margin or 'as configured'}: "
          f"{values.shape[1]} base parameters; mean sum of z^2 {z2.mean():.1f}")
    print(f"empirical / reported standard error: median {np.median(ratio):.3f}, quartiles "
          f"{np.percentile(ratio, 25):.3f} - {np.percentile(ratio, 75):.3f}")
    print(f"mean - truth in standard errors of the mean (1 expected without bias): RMS "
          f"{np.sqrt(np.mean((bias * np.sqrt(draws)) ** 2)):.2f}; largest in empirical standard errors:")
    for i in np.argsort(-np.abs(bias))[:4]:
        print(f"  {res.ols.names[i]:28s} {bias[i]:+.2f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--memory", action="store_true")
    parser.add_argument("--seeds", type=int, default=0)
    parser.add_argument("--monte-carlo", type=int, default=0)
    parser.add_argument("--case", default="ur5_coupled", choices=CASES)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cutoff-margin", type=float, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.memory:
            memory_table(Path(tmp))
        if args.seeds:
            seeds_table(Path(tmp), args.seeds)
        if args.monte_carlo:
            monte_carlo(Path(tmp), args.case, args.seed, args.monte_carlo, args.cutoff_margin)
