"""Which model-selection criterion agrees with the error on another session? (issue 32, docs/validation.md)

    OMP_NUM_THREADS=1 python benchmarks/selection_study.py [--part sim|tiago|all] [--seeds N] [--out FILE.json]

A ladder of models (`ladder`: registration, offsets, offsets + compliance, full, full + compliance, + backlash,
+ tilt; each with no prior, the default evidence-scaled prior, and explicit priors 2 mm / 10 mrad on the
placement errors of the full rungs; each for one tracked point and for the rigid body's four points) is fitted
on one session. Every criterion of benchmarks/selection_rungs.py is computed from that session alone and
compared with the target: the error of point BL (the body's first point) on another session.

- sim: simulated robots (benchmarks/selection_sim.py: TIAGo on the shipped sessions' joint readings, a UR5 on
  a random plan) with geometric errors, compliance, backlash and two unmodelled effects (link bending, encoder
  eccentricity), a new tracker placement every session. The fitting session is a subset of the plan; the
  target session is the whole plan (repeated and new postures: the TIAGo protocol's situation), and for the
  UR5 also fresh random postures. Criteria: as above, plus leave-one-session-out on a second session of the
  plan (`loso`). Targets with the base refitted (the tracker moved).
- tiago: the shipped sessions, training (2021-11-30) and validation (2021-11-26), each way; targets with the
  tracker frame kept and refitted.

Per setting and criterion the table gives the target error of the rung the criterion picks, the best rung's,
and how often the criterion's pick is within 5 % of the best. Only the shipped sessions are used.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(1, str(ROOT / "benchmarks"))
from robocal.design.simulate import random_configurations  # noqa: E402
from robocal.model.robot import load_example, load_urdf  # noqa: E402
from robocal.estimation.model_selection import one_standard_error  # noqa: E402
from selection_rungs import Rung, score  # noqa: E402
from selection_sim import SimRobot, base_for_session, configs, draw_truth, write_session  # noqa: E402

DATA = ROOT / "examples" / "tiago_mocap" / "data"
TRAINING, VALIDATION = DATA / "qualisys_2021-11-30_static_postures.csv", DATA / "qualisys_2021-11-26_static_postures.csv"
TIAGO_JOINTS = ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)]
UR5_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint"]
BL = np.array([0.054, -0.003, 0.072])
TIAGO = SimRobot("tiago", {"urdf": str(DATA / "tiago_48_schunk.urdf")}, TIAGO_JOINTS, "wrist_ft_tool_link",
                 BL + np.array([[0, 0, 0], [0, 0.15, 0], [-0.09, 0.15, 0], [-0.09, 0, 0]]),
                 compliant=["arm_2_joint", "arm_4_joint", "arm_6_joint"], play=["arm_5_joint", "arm_6_joint"],
                 bending="arm_3_joint", eccentric=["arm_4_joint", "arm_6_joint"],
                 tilt=["torso_lift_joint", "arm_1_joint"], base0=np.array([0.011, 0.214, -0.334, 0.021, 0.0, -0.006]))
UR5 = SimRobot("ur5", {"example": "ur5"}, UR5_JOINTS, "tool0",
               np.array([[0.05, 0, 0.03], [-0.05, 0, 0.03], [-0.05, 0.08, 0.03], [0.05, 0.08, 0.03]]),
               compliant=["shoulder_lift_joint", "elbow_joint", "wrist_1_joint"], play=["elbow_joint", "wrist_2_joint"],
               bending="shoulder_lift_joint", eccentric=["shoulder_pan_joint", "wrist_1_joint"],
               tilt=["shoulder_pan_joint"], base0=np.array([1.0, 0.2, 0.1, 0.0, 0.0, 0.3]))
PRIOR_2MM = {"priors": {"*_joint.t?": 2e-3, "*_joint.r?": 1e-2}}
STRENGTHS = (0.03, 0.1, 0.3, 1.0, 3.0)     # the prior-strength path: sigma = strength x physical scale
SCENARIOS = ("geometric", "compliance", "all")


STRUCTURES = ("registration", "offsets", "offsets + compliance", "full", "full + compliance",
              "full + compliance + backlash", "full + compliance + backlash + tilt")


def ladder(sim: SimRobot, measurement: str) -> list[Rung]:
    """Every structure with no prior, the default prior (auto), the evidence's prior always applied, explicit
    2 mm / 10 mrad (full structures), and the strength path (the selection rule's grid)."""
    off = {"compliance": False, "backlash": False, "tilt": False}
    pars = [{"preset": "none"}, {"preset": "offsets"}, {"preset": "offsets", "compliance": True}, {"preset": "full"},
            {"preset": "full", "compliance": True}, {"preset": "full", "compliance": True, "backlash": True},
            {"preset": "full", "compliance": True, "backlash": True, "tilt": sim.tilt}]
    rungs = []
    for label, par in zip(STRUCTURES, pars):
        priors = ["none"] if label == "registration" else (
            ["none", "auto", "evidence"] + (["2 mm / 10 mrad"] if label.startswith("full") else [])
            + [f"strength {lam:g}" for lam in STRENGTHS])
        for prior in priors:
            extra = PRIOR_2MM if prior == "2 mm / 10 mrad" else {}
            rungs.append(Rung(f"{measurement}: {label} [{prior}]", measurement, {**off, **par, **extra}, prior))
    return rungs


def structure_of(label: str) -> str:
    return label.split(": ", 1)[1].rsplit(" [", 1)[0]


def run_ladder(cfgs: dict, sim: SimRobot, train, others: dict, loo: bool, cross_fit=None, k: int = 5) -> list[dict]:
    """Score every rung; the brute-force cross-validations (K-fold, leave-one-out) only on the rungs that are
    not on the strength path (they cost a fit per fold)."""
    rows = []
    for measurement, config in cfgs.items():
        for rung in ladder(sim, measurement):
            path = rung.prior.startswith("strength")
            s = score(config, train, rung, others, point=0, k=0 if path else k, loo=loo and not path,
                      cross_fit=cross_fit)
            rows.append({"rung": rung.label, "structure": structure_of(rung.label), "measurement": measurement,
                         "prior": rung.prior, "n_free": s.n_free, "status": s.status, "seconds": s.seconds,
                         **s.values, **{f"target {k}": v for k, v in s.targets.items()}})
            print(f"  {rung.label:<62} {s.seconds:5.1f} s  " +
                  " ".join(f"{k} {v:.3g}" for k, v in s.values.items() if k in ("aloo", "kfold", "loo", "evidence")) +
                  "  | " + " ".join(f"{k} {v:.3g}" for k, v in s.targets.items()), flush=True)
    return rows


def tiago_real(folder: Path) -> list[dict]:
    cfgs = configs(TIAGO, folder)
    out = []
    for name, train, other in (("training -> validation", TRAINING, ("validation", VALIDATION)),
                               ("validation -> training", VALIDATION, ("training", TRAINING))):
        print(f"TIAGo, {name}", flush=True)
        for row in run_ladder(cfgs, TIAGO, train, {other[0]: other[1]}, loo=True):
            out.append({"setting": f"tiago real, {name}", **row})
    return out


def _plan(sim: SimRobot, rng) -> dict:
    """Readings and times of the sessions: fit (a subset of the plan), loso and target (the whole plan, new
    tracker placements), fresh (UR5 only: new random postures)."""
    if sim.name == "tiago":
        fit, whole = _columns(TRAINING, sim.joints), _columns(VALIDATION, sim.joints)
        return {"fit": fit, "loso": whole, "target": whole}
    robot = load_example("ur5")
    q = random_configurations(robot, sim.joints, 60, rng, span=0.45)
    t = np.arange(60) * 15.0
    keep = np.sort(rng.choice(60, 36, replace=False))
    fresh = random_configurations(robot, sim.joints, 60, rng, span=0.45)
    return {"fit": (q[keep], t[keep]), "loso": (q, t), "target": (q, t), "fresh": (fresh, t)}


def _columns(csv: Path, joints: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(joint readings, t_start_robot) of a session file."""
    tab = np.genfromtxt(csv, delimiter=",", names=True)
    return np.column_stack([tab[j] for j in joints]), tab["t_start_robot"]


def simulated(folder: Path, seeds: int, kfolds: int = 5) -> list[dict]:
    out = []
    for sim in (TIAGO, UR5):
        cfgs = configs(sim, folder)
        for scenario in SCENARIOS:
            for seed in range(seeds):
                rng = np.random.default_rng([2032, SCENARIOS.index(scenario), seed, len(sim.name)])
                plan = _plan(sim, rng)
                csv = {k: folder / f"{sim.name}_{scenario}_{seed}_{k}.csv" for k in plan}
                for k in plan:       # placeholder rows for the truth's set-up (joint readings only matter)
                    write_session(sim, cfgs["hand"], csv[k], *plan[k], {"values": {}, "effects": {
                        "bending": 0.0, "eccentricity": {}}}, sim.base0, rng)
                truth = draw_truth(sim, cfgs["hand"], csv["fit"], rng, scenario)
                for k in plan:
                    write_session(sim, cfgs["hand"], csv[k], *plan[k], truth, base_for_session(sim, rng, k != "fit"),
                                  rng)
                print(f"{sim.name}, {scenario}, seed {seed}", flush=True)
                others = {k: csv[k] for k in plan if k in ("target", "fresh")}
                for row in run_ladder(cfgs, sim, csv["fit"], others, loo=False, cross_fit={"second": csv["loso"]}, k=kfolds):
                    out.append({"setting": f"{sim.name} sim, {scenario}", "seed": seed, **row})
    return out


SHOWN = ("train", "loo", "kfold", "aloo", "aloo_in", "gcv", "fpe", "aic", "bic", "evidence", "loso")


def value(r: dict, criterion: str) -> float:
    """A criterion's value on a rung; the evidence needs a proper prior, so a rung without one has none."""
    v = r.get(criterion)
    return np.nan if v is None or (criterion == "evidence" and r.get("prior") == "none") else float(v)


def pick(recs: list[dict], criterion: str) -> int | None:
    """The rung a criterion picks among the rungs off the strength path (every criterion sees the same set)."""
    idx = [k for k, r in enumerate(recs) if not r["prior"].startswith("strength") and np.isfinite(value(r, criterion))]
    if not idx:
        return None
    v = np.array([value(recs[k], criterion) for k in idx])
    return idx[int(np.argmax(v) if criterion == "evidence" else np.argmin(v))]


def rule_pick(recs: list[dict], one_se: bool = True) -> int:
    """docs/validation.md's rule on one session: each structure at the strength of the grid (no prior, or the
    strength path) with the lowest closed-form leave-one-out RMS, then the one-standard-error rule over the
    structures in ladder order (one_se False: the lowest)."""
    chosen = []
    for structure in dict.fromkeys(r["structure"] for r in recs):
        grid = [k for k, r in enumerate(recs) if r["structure"] == structure and
                (r["prior"] == "none" or r["prior"].startswith("strength"))]
        chosen.append(min(grid, key=lambda k: recs[k]["aloo"]))
    rms = np.array([recs[k]["aloo"] for k in chosen])
    se = np.array([recs[k].get("aloo_se", np.nan) for k in chosen])
    return chosen[one_standard_error(rms, se if one_se else np.zeros_like(se))[0]]


def ladders(rows: list[dict]) -> dict:
    out: dict = {}
    for r in rows:
        out.setdefault((r["setting"], r["measurement"], r.get("seed", 0), r.get("run")), []).append(r)
    return out


def targets_of(setting: str, rec: dict) -> list[str]:
    return sorted(c for c in rec if c.startswith("target") and not ("sim" in setting and "kept" in c))


def summary(rows: list[dict]) -> list[str]:
    """Pooled over the ladders of each robot: for every criterion the mean regret (its pick's target error over
    the best rung's, minus one) and the share of ladders where its pick is within 5 % of the best."""
    regret: dict = {}
    for (setting, measurement, *_), recs in ladders(rows).items():
        group = setting.split(",")[0]
        for target in targets_of(setting, recs[0]):
            t = np.array([r.get(target, np.nan) for r in recs], float)
            best = np.nanmin(t)
            picks = {c: pick(recs, c) for c in SHOWN}
            picks["rule"] = rule_pick(recs)
            picks["rule, lowest"] = rule_pick(recs, one_se=False)
            for c, k in picks.items():
                if k is not None:
                    regret.setdefault(group, {}).setdefault(c, []).append(t[k] / best - 1)
    lines = ["Mean regret of each criterion's pick (target error / best rung's - 1) and share within 5 % of the best:"]
    for group, per in regret.items():
        lines.append(f"  {group}: " + "; ".join(f"{c} {100 * np.mean(v):.1f} % ({np.mean(np.array(v) <= 0.05):.0%}, "
                                               f"n={len(v)})" for c, v in per.items()))
    return lines


def real_table(rows: list[dict]) -> list[str]:
    """The shipped TIAGo sessions: every rung with its criteria and its error on the other session."""
    lines = []
    for (setting, measurement, *_), recs in ladders(rows).items():
        if "real" not in setting:
            continue
        tg = targets_of(setting, recs[0])
        lines.append(f"{setting}, {measurement}: norm RMS of BL (mm); evidence in nats; other session: "
                     + ", ".join(t.removeprefix("target ") for t in tg))
        lines.append(f"| rung | free | train | LOO | 5-fold | closed-form LOO | evidence | "
                     + " | ".join(t.removeprefix("target ") for t in tg) + " | status |")
        lines.append("|---" * (8 + len(tg)) + "|")
        marks = {c: pick(recs, c) for c in ("loo", "kfold", "aloo", "bic", "evidence")}
        rule = rule_pick(recs)
        for k, r in enumerate(recs):
            label = r["rung"].split(": ", 1)[1] + (" **(rule)**" if k == rule else "")
            lines.append(f"| {label} | {r['n_free']} | " + " | ".join(
                "" if not np.isfinite(value(r, c)) else f"{value(r, c):.{1 if c == 'evidence' else 2}f}"
                for c in ("train", "loo", "kfold", "aloo", "evidence")) + " | "
                + " | ".join(f"{r[t]:.2f}" for t in tg) + f" | {r['status']} |")
        lines.append("criteria's picks: " + "; ".join(f"{c}: {recs[k]['rung'].split(': ', 1)[1]}"
                                                      for c, k in marks.items() if k is not None)
                     + f"; rule: {recs[rule]['rung'].split(': ', 1)[1]}")
        lines.append("")
    return lines


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=("sim", "tiago", "all"), default="all")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--kfold", type=int, default=5, help="K of the K-fold criterion in the simulations (0: none)")
    ap.add_argument("--out", type=Path, default=None, help="write every rung's figures here (JSON)")
    ap.add_argument("--tables", type=Path, nargs="*", help="only print the tables of earlier --out files")
    args = ap.parse_args(argv)
    rows = []
    if args.tables:
        for f in args.tables:
            rows += [{"structure": structure_of(r["rung"]), "run": f.name, **r} for r in json.loads(f.read_text())]
    else:
        with tempfile.TemporaryDirectory(prefix="robocal_selection_") as tmp:
            if args.part in ("sim", "all"):
                rows += simulated(Path(tmp), args.seeds, args.kfold)
            if args.part in ("tiago", "all"):
                rows += tiago_real(Path(tmp))
        if args.out:
            args.out.write_text(json.dumps(rows, indent=1, default=float))
    print("\n".join([""] + real_table(rows) + summary(rows)))


if __name__ == "__main__":
    main()
