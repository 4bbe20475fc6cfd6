"""Why robocal's full model on point BL predicted worse than FIGAROH 1.0.2's full_params, and the full rung the
selection rule gives (issue 32, part 2; docs/tiago_mocap.md "The full rung against FIGAROH").

    OMP_NUM_THREADS=1 python benchmarks/tiago_full_rung.py [--reverse]

Every model is examples/tiago_mocap/full_bl.yaml (base frame, BL's position on the tool, every joint's offset and
6D placement error), fitted on the training session; BL's norm RMS (mm) on training, its closed-form
leave-one-out, and on the validation session with the training session's tracker frame ("kept") and with the
tracker frame refitted there ("refit"):
- robocal's selection at the config's start (BL guessed at the tool frame's origin, on arm_7's axis);
- the same selection made at the registered nominal (BL where the registration puts it);
- FIGAROH's 30 parameters (the set its structural selection keeps on Linux, from its own run:
  benchmarks/figaroh/calibration_driver.py in 'script' mode), every other parameter held at nominal;
- the default prior (one strength per scale family) and, for comparison, its best common strength;
- the selection rule's full rung (docs/validation.md): the default prior at the strength of the grid with the
  lowest closed-form leave-one-out error by posture.

--reverse fits every model on the validation session (62 postures) and scores it on the training session (37):
the second split of the two shipped sessions. FIGAROH's set is the same there: its selection is structural (random
postures within the joint limits), not made on the session's data.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from robocal import calibrate  # noqa: E402
from robocal.estimation import model_criteria as mc  # noqa: E402
from strength_rule import STRENGTH_GRID, rung_by_postures  # noqa: E402
from robocal.estimation.registration import register_nominal  # noqa: E402
from robocal.estimation.session_holdout import score_session  # noqa: E402
from robocal.workflows import setup_for_data  # noqa: E402

CONFIG = ROOT / "examples" / "tiago_mocap" / "full_bl.yaml"
VALIDATION = ROOT / "examples" / "tiago_mocap" / "data" / "qualisys_2021-11-26_static_postures.csv"
TRAINING = ROOT / "examples" / "tiago_mocap" / "data" / "qualisys_2021-11-30_static_postures.csv"   # full_bl's csv
FIT, SCORE = TRAINING, VALIDATION      # --reverse swaps them
# FIGAROH 1.0.2's full_params set on this data (Linux), in robocal's names: d_p* -> t*, d_phix/y -> rx/ry,
# d_phiz (the rotation about a joint's own z axis) -> offset; its base (6) and marker (3) are base.* and BL.point.*
FIGAROH_SET = ["arm_1_joint.ry", "arm_2_joint.tx", "arm_2_joint.rx", "arm_2_joint.offset", "arm_3_joint.tx",
               "arm_3_joint.ty", "arm_3_joint.tz", "arm_3_joint.rx", "arm_4_joint.ty", "arm_4_joint.rx",
               "arm_4_joint.ry", "arm_4_joint.offset", "arm_5_joint.tx", "arm_5_joint.ty", "arm_5_joint.tz",
               "arm_5_joint.ry", "arm_5_joint.offset", "arm_6_joint.ty", "arm_6_joint.tz", "arm_6_joint.ry",
               "arm_7_joint.tx"]


def scores(parameters, setup, result) -> dict:
    """Training, closed-form leave-one-out and validation figures of a fitted `setup` (its `parameters`)."""
    block = setup.problem.residuals[0].name
    lin = mc.linearise(setup.problem)
    _, train = mc.norms(lin, lin.r[lin.data] / lin.scale[lin.data])
    _, loo = mc.held_out_norms(setup.problem)
    fitted = setup.problem.params
    kept = score_session(fitted, setup_for_data(CONFIG, SCORE, parameters).problem, per_session=())
    refit = score_session(fitted, setup_for_data(CONFIG, SCORE, parameters).problem, options=setup.options)
    return {"free": len(result.params.free_names), "status": result.status, "train": mc.rms(train),
            "loo": mc.rms(loo), "kept": kept[block].point_stats(0).rmse_norm,
            "refit": refit[block].point_stats(0).rmse_norm,
            "kept_norms": 1e3 * np.linalg.norm(kept[block].points()[:, 0], axis=1),      # mm
            "refit_norms": 1e3 * np.linalg.norm(refit[block].points()[:, 0], axis=1)}


def paired_difference(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """RMS(a) - RMS(b) of two models' error norms on the same postures, and its standard error: the delta
    method on the per-posture terms a_i^2 / (2 RMS(a)) - b_i^2 / (2 RMS(b)), which keeps the pairing."""
    ra, rb = np.sqrt(np.mean(a ** 2)), np.sqrt(np.mean(b ** 2))
    g = a ** 2 / (2 * ra) - b ** 2 / (2 * rb)
    return float(ra - rb), float(np.std(g, ddof=1) / np.sqrt(len(g)))


def fit(parameters=None, regularisation="none", strength=None):
    setup = setup_for_data(CONFIG, FIT, parameters)
    setup.options.regularisation, setup.options.prior_strength = regularisation, strength
    return parameters, setup, calibrate(setup.problem, setup.options)


def main() -> None:
    global FIT, SCORE
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reverse", action="store_true", help="fit on the validation session, score on training")
    if ap.parse_args().reverse:
        FIT, SCORE = SCORE, FIT
    print(f"fitted on {FIT.name}, scored on {SCORE.name} (point BL, mm)")
    start = setup_for_data(CONFIG, FIT)
    reg = register_nominal(start.problem, start.options).values
    figure = rung_by_postures(lambda: setup_for_data(CONFIG, FIT).problem, start.options, STRENGTH_GRID)
    default = fit(regularisation="auto")
    common = default[2].default_prior.strength     # the evidence's best common strength: the default before
    rows = [("robocal, selection at the config's start (published full_bl)", fit()),
            ("robocal, selection at the registered nominal", fit({"initial": reg})),
            ("FIGAROH 1.0.2's 30 parameters, fitted by robocal",
             fit({"fix": ["*"], "free": ["base.*", "BL.point.*"] + FIGAROH_SET})),
            ("robocal default prior (strength per scale family by the evidence)", default),
            ("the same, one common strength (before the per-family rule)", fit(regularisation="auto", strength=common)),
            (f"selection rule: strength {figure.strength} (closed-form LOO by posture)",
             fit(regularisation="auto" if figure.strength is not None else "none", strength=figure.strength))]
    print("| model | free | status | fitted session | closed-form LOO | other session, tracker kept | "
          "other session, tracker refit |")
    print("|---|---|---|---|---|---|---|")
    figures = [scores(*fitted) for _, fitted in rows]
    for (label, (parameters, setup, result)), f in zip(rows, figures):
        print(f"| {label} | {f['free']} | {f['status']} | {f['train']:.2f} | {f['loo']:.2f} | {f['kept']:.2f} | "
              f"{f['refit']:.2f} |")
    figaroh = figures[2]
    print(f"\nagainst FIGAROH's 30 parameters on the {len(figaroh['kept_norms'])} postures of the other session, paired "
          "(RMS difference +- its standard error, mm; negative: better than FIGAROH's):")
    for (label, _), f in zip(rows, figures):
        kept, refit = (paired_difference(f[k], figaroh[k]) for k in ("kept_norms", "refit_norms"))
        print(f"  {label}: tracker kept {kept[0]:+.2f} +- {kept[1]:.2f}, refit {refit[0]:+.2f} +- {refit[1]:.2f}")
    first, second = rows[0][1][2], rows[1][1][2]
    print("\nselection at the registered nominal adds: "
          + ", ".join(sorted(set(second.params.free_names) - set(first.params.free_names))))
    print("the rule's strength grid (closed-form LOO by posture, mm): "
          + ", ".join(f"{s}: {v:.2f}" for s, v, _ in figure.per_strength))
    prior = default[2].default_prior
    if not prior.applied:
        print(f"default prior not applied: {prior.reason} (its rows are the fit without a prior)")
        return
    print(f"default prior of the evidence: common strength {prior.strength:.3g}; by scale family "
          + ", ".join(f"{f} {v:.3g}" for f, v in prior.by_family.items()))


if __name__ == "__main__":
    main()
