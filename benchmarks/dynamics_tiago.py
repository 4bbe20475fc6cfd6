"""Benchmark: dynamic identification of the shipped TIAGo log through its config alone.

    OMP_NUM_THREADS=1 python benchmarks/dynamics_tiago.py [--repeats N] [--config YAML] [--figaroh [--figaroh-venv PATH]]

Prints the held-out torque RMSE per recorded joint for the CAD model (the baseline, same run), the
OLS base parameters and the physically consistent model, the free-motion external force, and the
wall time of the whole identification (best and median of N runs).

--figaroh also runs FIGAROH 1.0.2's identification pipeline, installed into its own virtual environment
(benchmarks/figaroh_env.py), the way its TIAGo example does (benchmarks/figaroh/identification_driver.py:
median + 2 Hz Butterworth filtering, decimation by 10, base parameters by double QR and OLS) on the rows of
the same training window (windows.train), N times, each in its own process, and scores it on the same
validation samples as robocal's models: the validation window's decimated samples (robocal's grid), against
(1) robocal's validation target, the logged torque low-pass filtered by the config's filter, and (2) the
logged torque itself (effort x gear ratio x motor constant + offset, linearly interpolated to those times).
FIGAROH's prediction there comes from its own held-out processing of the shipped log (see the driver),
linearly interpolated from the log's time stamps to the same times.
"""
import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))          # this tree's robocal, not an installed one
sys.path.insert(1, str(ROOT / "benchmarks"))

import numpy as np  # noqa: E402

from figaroh_env import add_options, figaroh_python, run_driver  # noqa: E402
import robocal.workflows.identify as identify_run  # noqa: E402
from robocal.dynamics.identify_log import MODELS
from robocal.workflows.identify import identify_from_config  # noqa: E402
from robocal.dynamics.log_loading import load_joint_log  # noqa: E402

CONFIG = ROOT / "examples/tiago_dynamics/identify.yaml"
FIGAROH_CONFIG = ROOT / "benchmarks/figaroh/tiago_identification.yaml"


# the stages of identify_from_config beyond the OLS fit, timed apart to compare like with like
EXTRA_STAGES = ("within_noise_choice", "_holdout_choice", "fit_consistent", "constraint_costs")


def time_extra_stages(spent: dict) -> None:
    """Wrap identify_run's prior-weight choice, consistent fit and constraint-cost refits so that their wall time
    adds up in `spent`."""
    for name in EXTRA_STAGES:
        def timed(*args, _f=getattr(identify_run, name), _name=name, **kwargs):
            t0 = time.perf_counter()
            out = _f(*args, **kwargs)
            spent[_name] = spent.get(_name, 0.0) + time.perf_counter() - t0
            return out
        setattr(identify_run, name, timed)


def figaroh_request(res) -> dict:
    """The driver's request: robocal's shipped files, the rows of its training window, its constants."""
    cfg = res.config
    t = load_joint_log({k: str(p) for k, p in cfg.files.items()}, cfg.joints, cfg.time_column, cfg.patterns).t
    rows = [int(np.searchsorted(t, cfg.train[0])), int(np.searchsorted(t, cfg.train[1]))]
    return {"config": str(FIGAROH_CONFIG), "urdf": str(cfg.urdf), "train_rows": rows,
            "validate": list(cfg.validate), "torque_scale": {j: float(cfg.torque_scale[j]) for j in cfg.recorded},
            **{kind: str(path) for kind, path in cfg.files.items()}}


def heldout_tables(res, figaroh: dict | None, units: list[str]) -> list[str]:
    """Per-joint held-out RMSE of CAD, FIGAROH, robocal OLS and consistent, against both targets."""
    times = res.curves["t"]
    predictions = {"CAD (URDF)": res.curves["cad"]}
    if figaroh:
        predictions["FIGAROH 1.0.2 (OLS)"] = np.column_stack(
            [np.interp(times, figaroh["t"], figaroh["predicted"][j]) for j in res.recorded])
    predictions.update({"robocal OLS": res.curves["ols"], "robocal consistent": res.curves["consistent"]})
    out, verdicts = [], []
    for title, target in (("low-pass filtered torque (robocal's validation target)", res.curves["measured"]),
                          ("logged torque, unfiltered", res.curves["logged"])):
        out += [f"\nheld-out torque RMSE on {len(times)} samples of {list(res.config.validate)} s, against the {title}",
                "| model | " + " | ".join(f"{j} ({u})" for j, u in zip(res.recorded, units)) + " |",
                "|---" * (len(res.recorded) + 1) + "|"]
        rmse = {name: np.sqrt(np.mean((pred - target) ** 2, axis=0)) for name, pred in predictions.items()}
        for name, r in rmse.items():
            out.append(f"| {name} | " + " | ".join(f"{v:.3f}" for v in r) + " |")
        consistent = rmse["robocal consistent"]
        checks = {"below CAD": consistent < rmse["CAD (URDF)"],
                  "within 5 % of OLS": consistent <= 1.05 * rmse["robocal OLS"]}
        if figaroh:
            checks["below FIGAROH"] = consistent < rmse["FIGAROH 1.0.2 (OLS)"]
        verdicts.append(f"against the {title.split(' (')[0]}: " + "; ".join(
            f"{k} on every joint: " + ("yes" if ok.all() else "NO (" + ", ".join(
                j for j, good in zip(res.recorded, ok) if not good) + ")") for k, ok in checks.items()))
    return out + ["\nissue 22, the consistent model " + verdicts[0], "issue 22, the consistent model " + verdicts[1]]


def run_figaroh(python, res, repeats: int) -> list[dict]:
    return [run_driver(python, "identification_driver.py", figaroh_request(res))[0] for _ in range(repeats)]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--config", default=str(CONFIG), help="another identification config (default: the shipped one)")
    add_options(ap)
    args = ap.parse_args(argv)
    python = figaroh_python(args)
    times, cpu, extra, res = [], [], [], None
    spent = {}
    time_extra_stages(spent)
    for _ in range(args.repeats):
        spent.clear()
        t0, c0 = time.perf_counter(), time.process_time()
        res = identify_from_config(args.config)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        extra.append(sum(spent.values()))
    units = ["N" if res.model.joints[res.model.getJointId(j)].shortname().startswith("JointModelP") else "N m"
             for j in res.recorded]
    print(f"config: {args.config}")
    print(f"train {list(res.config.train)} s ({res.train.sum()} samples), validate {list(res.config.validate)} s "
          f"({res.check.sum()} samples); cut-off {res.processed.cutoff_hz:.3g} Hz, "
          f"decimation {res.processed.decimation}")
    print(f"OLS: {res.ols.selection.rank} base parameters, condition {res.ols.condition:.4g}; consistent: prior weight "
          f"{res.consistent.prior_weight:g} (rule {res.prior.rule}; grid scores "
          + ", ".join(f"{s:.3f}" for s in res.prior.scores)
          + f"), Clarabel {res.consistent.iterations} iterations, status {res.consistent.status}")
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
    print(f"\nconsistent vs OLS on the training window: squared distance {wn['distance_in_noise_units']:.1f} "
          f"in noise units (variance inflation of the filtered noise {wn['noise_inflation']:.3g}; chi-square 95 %: "
          f"{wn['chi2_95']:.1f}); "
          "RMS ratio " + ", ".join(f"{r:.3f}" for r in wn["rms_ratio"]))
    print(f"\nidentification wall time (load, filter, OLS, prior-weight grid, consistent fit, constraint costs, "
          "validation): "
          f"best {min(times):.2f} s, median {np.median(times):.2f} s over {len(times)} run(s); "
          f"CPU time best {min(cpu):.2f} s (the machine may be shared); of which the prior-weight grid, the "
          f"consistent fit and the constraint-cost refits: median {np.median(extra):.2f} s, the rest (load, filter, regressor, OLS, validation, "
          f"external force) median {np.median(np.subtract(times, extra)):.2f} s")
    if python is None:
        return
    figaroh = run_figaroh(python, res, args.repeats)
    f = figaroh[0]
    print(f"\nFIGAROH {f['base_parameters']} base parameters from {f['training_samples']} samples "
          f"({f['fit_rows']} rows after decimation), condition {f['condition']:.4g}; torso offset "
          f"9.81 x {f['torso_carried_mass_kg']:.4g} kg (robocal's config: {res.config.torque_offset})")
    print("\n".join(heldout_tables(res, f, units)))
    fig_times = [a["identification_s"] for a in figaroh]
    print(f"\nidentification wall time, median of {len(times)} run(s): robocal, whole identify_from_config "
          f"{np.median(times):.2f} s, without the prior-weight grid, consistent fit and constraint costs "
          f"{np.median(np.subtract(times, extra)):.2f} s; FIGAROH (its own process, robot model to solve() "
          f"returned: load, filter, regressor, decimation, double QR, OLS, its report) {np.median(fig_times):.2f} s "
          f"(range {min(fig_times):.2f}-{max(fig_times):.2f} s). The machine is shared with other jobs: compare "
          "within one run.")


if __name__ == "__main__":
    main()
