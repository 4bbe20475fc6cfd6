"""Benchmark: dynamic identification of the shipped TIAGo log through its config alone.

    OMP_NUM_THREADS=1 python benchmarks/dynamics_tiago.py [--repeats N] [--config YAML] [--splits]
                                                          [--figaroh [--figaroh-venv PATH]]

--splits: the shipped config's log cut into the three splits of docs/dynamics_tiago.md (all inside FIGAROH's
example window, 9.2-60 s of the shipped rows: 9.2-40 s trained / 40-60 s held out, 9.2-45 / 45-60, and
29.2-60 / 9.2-29.2), each identified as configured and scored like a validation window, FIGAROH on the
same training rows; then the shipped config itself (trained on the whole window, no validation) timed
against FIGAROH on the same rows. Also printed per split: the held-out RMSE at the log's raw rows against
the logged torque of the model robocal writes (URDF + side file, through `robocal evaluate`'s path) and of
FIGAROH's prediction at the same rows (each with its own kinematics).

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
import copy  # noqa: E402
import tempfile  # noqa: E402

import yaml  # noqa: E402

import robocal.dynamics.identify_log as identify_run  # noqa: E402
from robocal.dynamics.identify_log import MODELS  # noqa: E402
from robocal.workflows.identify import identify_from_config  # noqa: E402
from robocal.workflows.identify_evaluate import evaluate_dynamics  # noqa: E402
from robocal.workflows.identify_outputs import write_identification  # noqa: E402
from robocal.dynamics.log_loading import load_joint_log  # noqa: E402

CONFIG = ROOT / "examples/tiago_dynamics/identify.yaml"
FIGAROH_CONFIG = ROOT / "benchmarks/figaroh/tiago_identification.yaml"


# the stages of identify_from_config beyond the OLS fit, timed apart to compare like with like
EXTRA_STAGES = ("within_noise_choice", "_holdout_choice", "fit_consistent", "constraint_costs")
#: (label, train, validate) in s of the shipped log: docs/dynamics_tiago.md, "Three splits"
SPLITS = (("9.2-40 / 40-60", [9.2, 40.0], [40.0, 60.0]), ("9.2-45 / 45-60", [9.2, 45.0], [45.0, 60.0]),
          ("29.2-60 / 9.2-29.2", [29.2, 60.0], [9.2, 29.2]))


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
    log = cfg.logs[0]
    t = load_joint_log({k: str(p) for k, p in log.files.items()}, cfg.joints, log.time_column, log.patterns).t
    train = log.train[0]
    rows = [int(np.searchsorted(t, train[0])), int(np.searchsorted(t, train[1]))]
    validate = list(log.validate[0]) if log.validate else [float(t[0]), float(t[0])]
    return {"config": str(FIGAROH_CONFIG), "urdf": str(cfg.urdf), "train_rows": rows,
            "validate": validate, "torque_scale": {j: float(cfg.torque_scale[j]) for j in cfg.recorded},
            **{kind: str(path) for kind, path in log.files.items()}}


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
        out += [f"\nheld-out torque RMSE on {len(times)} samples of {res.config.logs[0].validate} s, against the {title}",
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
    return out + ["\nthe consistent model " + verdicts[0], "the consistent model " + verdicts[1]]


def run_figaroh(python, res, repeats: int) -> list[dict]:
    return [run_driver(python, "identification_driver.py", figaroh_request(res))[0] for _ in range(repeats)]


def raw_rows_table(res, figaroh: dict | None) -> list[str]:
    """Held-out RMSE at the log's raw rows against the logged torque: the written model (robocal evaluate's
    path) and FIGAROH's prediction at the same rows."""
    log = res.config.logs[0]
    with tempfile.TemporaryDirectory() as tmp:
        write_identification(res, Path(tmp) / "out")
        spec = Path(tmp) / "log.yaml"
        spec.write_text(yaml.safe_dump({"name": "heldout", "window": list(log.validate[0]),
                                        **{k: str(p) for k, p in log.files.items()}}))
        ev = evaluate_dynamics(Path(tmp) / "out", spec)
    lines = [f"\nheld-out RMSE at the log's raw rows ({len(ev.t)} rows of {list(log.validate[0])} s, the filter's "
             "trimmed edges left out), against the logged torque",
             "| model | " + " | ".join(f"{j} ({u})" for j, u in zip(ev.recorded, ev.units)) + " |",
             "|---" * (len(ev.recorded) + 1) + "|",
             "| robocal, written URDF + side file | " + " | ".join(f"{v:.3f}" for v in ev.rmse_logged) + " |"]
    if figaroh:
        pred = np.column_stack([np.interp(ev.t, figaroh["t"], figaroh["predicted"][j]) for j in ev.recorded])
        rmse = np.sqrt(np.mean((pred - ev.logged) ** 2, axis=0))
        lines.append("| FIGAROH 1.0.2 (OLS) | " + " | ".join(f"{v:.3f}" for v in rmse) + " |")
        better = ev.rmse_logged < rmse
        lines.append("robocal's written model below FIGAROH on every joint: " + (
            "yes" if better.all() else "NO (" + ", ".join(j for j, b in zip(ev.recorded, better) if not b) + ")"))
    return lines


def run_splits(args, python) -> None:
    base = yaml.safe_load(Path(args.config).read_text())
    for label, train, validate in SPLITS:
        cfg = copy.deepcopy(base)
        cfg["logs"][0]["train"], cfg["logs"][0]["validate"] = train, validate
        res = identify_from_config(cfg, Path(args.config).parent)
        units = ["N" if res.model.joints[res.model.getJointId(j)].shortname().startswith("JointModelP") else "N m"
                 for j in res.recorded]
        print(f"\n## split {label} s: {res.n_train} training, {res.n_check} held-out samples; prior weight "
              f"{res.prior.chosen:g}; terms kept: "
              + (", ".join(f"{t.joint}.{t.term}" for t in res.term_tests if t.kept) or "none")
              + "; masses (kg): " + ", ".join(f"{m:.3g}" for m in res.consistent.inertial[0::10]))
        f = run_figaroh(python, res, 1)[0] if python else None
        print("\n".join(heldout_tables(res, f, units)))
        print("\n".join(raw_rows_table(res, f)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--config", default=str(CONFIG), help="another identification config (default: the shipped one)")
    ap.add_argument("--splits", action="store_true", help="also the three splits of docs/dynamics_tiago.md")
    add_options(ap)
    args = ap.parse_args(argv)
    python = figaroh_python(args)
    if args.splits:
        run_splits(args, python)
        print("\n## the shipped config")
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
    print(f"\nconfig: {args.config}")
    print(f"{res.n_train} training samples, {res.n_check} held out; cut-off {res.processed.cutoff_hz:.3g} Hz, "
          f"decimation {res.processed.decimation}")
    print(f"OLS: {res.ols.selection.rank} base parameters, condition {res.ols.condition:.4g}; consistent: prior weight "
          f"{res.consistent.prior_weight:g} (rule {res.prior.rule}), Clarabel {res.consistent.iterations} iterations, "
          f"status {res.consistent.status}; masses (kg) " + ", ".join(f"{m:.3g}" for m in res.consistent.inertial[0::10])
          + "; training RMS consistent " + ", ".join(f"{r:.3f}" for r in res.training_rms["consistent"])
          + ", OLS " + ", ".join(f"{r:.3f}" for r in res.training_rms["ols"]))
    if res.validation:
        print("\n".join(heldout_tables(res, None, units)))
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
          f"({f['fit_rows']} rows after decimation), condition {f['condition']:.4g}")
    if res.validation:
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
