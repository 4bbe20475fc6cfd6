"""Time of `robocal select` on the TIAGo example (examples/tiago_mocap/select_bl.yaml, 37 postures, 5 folds,
4 rungs), against one `calibrate` of the same config measured in the same run.

Run: OMP_NUM_THREADS=1 python benchmarks/select_tiago.py
"""
import time
from pathlib import Path

from robocal.estimation.calibrate import calibrate
from robocal.workflows.evaluate import setup_for_data
from robocal.workflows.select import select_model

CONFIG = Path(__file__).parents[1] / "examples" / "tiago_mocap" / "select_bl.yaml"


def main() -> None:
    t0 = time.perf_counter()
    setup = setup_for_data(CONFIG)
    calibrate(setup.problem, setup.options)
    one = time.perf_counter() - t0
    t0 = time.perf_counter()
    selection = select_model(CONFIG, folds=5)
    total = time.perf_counter() - t0
    print("\n".join(selection.table()))
    print()
    print(f"{'what':<44}{'seconds':>10}")
    print(f"{'one calibrate (full + compliance, baseline)':<44}{one:>10.2f}")
    print(f"{'select (4 rungs x 5 folds, cross-validated)':<44}{total:>10.2f}")


if __name__ == "__main__":
    main()
