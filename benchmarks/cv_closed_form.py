"""Benchmark: `robocal cv`'s closed-form leave-out updates against refitting every fold, on the shipped examples.

    OMP_NUM_THREADS=1 python benchmarks/cv_closed_form.py [--only WORD] [--loo-only]

For each config (the demo UR5, examples/tiago_mocap/*.yaml, examples/closed_loops/*.yaml, the camera) and each of 5-fold by
posture and leave-one-posture-out: the held-out RMS of the error norm, its standard error across folds and the
train RMS, from the closed form (robocal.estimation.leave_out, what `robocal cv` does by default) and from refits
(`robocal cv --refits`), the largest difference of a fold's held-out RMS, and the CPU seconds of each (in this
process, after the imports). A config the closed form does not allow says why (it is then refitted both ways).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from robocal.workflows.cv import run_cv

ROOT = Path(__file__).resolve().parents[1]


def configs() -> list[tuple[str, Path]]:
    out = [("demo ur5", ROOT / "robocal" / "io" / "demo" / "ur5_calibrate.yaml")]
    out += [(f"tiago {p.stem}", p) for p in sorted((ROOT / "examples" / "tiago_mocap").glob("*.yaml"))]
    out += [(f"closed {p.stem}", p) for p in sorted((ROOT / "examples" / "closed_loops").glob("*.yaml"))]
    out.append(("camera", ROOT / "examples" / "camera" / "camera.yaml"))
    return out


def timed(*args, **kw):
    t0 = time.process_time()
    out = run_cv(*args, **kw)
    return out, time.process_time() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", action="append", default=[], help="configs whose label holds this word")
    ap.add_argument("--loo-only", action="store_true", help="leave-one-posture-out only")
    args = ap.parse_args()
    print(f"{'example':<44}{'folds':>6}  {'closed form: RMS +- se (train)':>32}  {'refits: RMS +- se (train)':>30}"
          f"{'max fold diff':>14}{'cpu closed':>11}{'cpu refits':>11}")
    for label, cfg in configs():
        if args.only and not any(w in label for w in args.only):
            continue
        for loo in ((True,) if args.loo_only else (False, True)):
            (closed, how, _), t_closed = timed(cfg, loo=loo)
            (refit, _, _), t_refit = timed(cfg, loo=loo, refits=True)
            diff = max(abs((a["validation_rms_norm"] or 0) - (b["validation_rms_norm"] or 0))
                       for a, b in zip(closed.folds, refit.folds))
            u = closed.unit
            line = (f"{label:<44}{'loo' if loo else '5':>6}  {closed.rms:>10.4g} +- {closed.stderr:<7.2g}"
                    f"({closed.train_rms:.4g})  {refit.rms:>10.4g} +- {refit.stderr:<7.2g}({refit.train_rms:.4g})"
                    f"{diff:>11.3g} {u}{t_closed:>10.2f}{t_refit:>11.2f}")
            if "closed-form" not in how:
                line += f"   [{how.split(', ')[-1]}]"
            print(line, flush=True)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
