"""Diagnostic: what each physical constraint of the consistent fit costs on held-out torques.

    OMP_NUM_THREADS=1 python benchmarks/dynamics_constraint_refits.py [--config YAML]

Runs the identification of the config (the shipped TIAGo log by default), then refits the consistent
model at the chosen prior weight with one kind of constraint dropped at a time (each body's PSD
constraint, all of them, each rotor inertia's bound at zero, all of those) and prints the held-out
torque RMSE of each refit over the OLS fit's, per recorded joint, against the filtered and the logged
torque. These refits are not models robocal offers (a negative rotor inertia is not physical): they
show which constraint the data push against (docs/dynamics_tiago.md, "What the constraints cost").
"""
import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))          # this tree's robocal, not an installed one

import numpy as np  # noqa: E402

from robocal.dynamics.consistent_fit import fit_consistent  # noqa: E402
from robocal.workflows.identify import identify_from_config  # noqa: E402
from robocal.dynamics.inertial import parameter_vector  # noqa: E402
from robocal.dynamics.plausible_bounds import linear_bounds  # noqa: E402

CONFIG = ROOT / "examples/tiago_dynamics/identify.yaml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument("--config", default=str(CONFIG), help="an identification config (default: the shipped one)")
    args = parser.parse_args()
    res = identify_from_config(args.config)
    reg_train, reg_check = res.regressors["train"], res.regressors["check"]
    if "check" not in res.regressors:
        raise SystemExit("the config has no validation window: add one (logs[].validate)")
    tau_train = np.concatenate([p.torque(p.train, res.delays) for p in res.parts])
    names = [res.model.names[j] for j in range(1, res.model.njoints)]
    bounds = linear_bounds(res.bounds, len(names), {n: i for i, n in enumerate(names)}) if res.bounds else None
    cad, sigma, lam = parameter_vector(res.model), res.ols.sigma, res.consistent.prior_weight
    filtered, logged = res.curves["measured"], res.curves["logged"]

    def rmse(pred, target):
        return np.sqrt(np.mean((pred - target) ** 2, axis=0))

    ols_pred = res.ols.predict(reg_check)
    bodies = [res.model.names[j] for j in range(1, res.model.njoints)]
    armatures = [n for n in res.consistent_extra_names() if n.endswith(".armature")]
    refits = {"every constraint (the shipped fit)": {}}
    refits.update({f"PSD of {b}'s body dropped": {"free_bodies": (k,)} for k, b in enumerate(bodies)})
    refits["every PSD constraint dropped"] = {"free_bodies": tuple(range(len(bodies)))}
    refits.update({f"{a} free in sign": {"free_terms": (a,)} for a in armatures})
    refits["every rotor inertia free in sign"] = {"free_terms": tuple(armatures)}
    print(f"{args.config}: prior weight {lam:.3g}; consistent / OLS held-out torque RMSE per recorded joint "
          f"({', '.join(res.recorded)})")
    print(f"{'refit':48s} {'against the filtered torque':>36s}   {'against the logged torque':>36s}")
    for label, relax in refits.items():
        pred = fit_consistent(reg_train, tau_train, sigma, cad, lam, bounds=bounds, **relax).predict(reg_check)
        f = rmse(pred, filtered) / rmse(ols_pred, filtered)
        g = rmse(pred, logged) / rmse(ols_pred, logged)
        print(f"{label:48s} " + " ".join(f"{v:6.3f}" for v in f) + "   " + " ".join(f"{v:6.3f}" for v in g))


if __name__ == "__main__":
    main()
