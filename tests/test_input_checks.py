"""The checks of a set-up's input before a fit (robocal.workflows.input_checks), on synthetic data built from
the UR5 demo (simulated: robocal/io/demo/ur5_tracker_poses_truth.json holds its truth).

The corpus (tests/bad_inputs, test_bad_input.py) holds one CLI case per bad input; here are the rules
behind them: repeated postures count once, at the boundary of the distinct-postures rule and in the fit.
"""
import csv
import glob
import re
from pathlib import Path

import numpy as np
import pytest

from robocal.errors import InputError
from robocal.estimation.calibrate import calibrate
from robocal.io.tables import read_csv
from robocal.workflows.input_checks import check_inputs
from robocal.workflows.posture_check import posture_counts
from robocal.workflows.setup import load_config

ROOT = Path(__file__).parents[1]
DEMO = ROOT / "robocal" / "io" / "demo"
OFFSETS = """robot: {example: ur5}
data: {csv: data.csv}
parameters: {preset: offsets, base: true}
measurements:
  - {type: pose, name: tracker, frame: tool0, columns: [x, y, z, qx, qy, qz, qw],
     sigma: {position: 5.0e-5, orientation: 5.0e-5}}
"""


def demo_rows():
    rows = list(csv.reader(open(DEMO / "ur5_tracker_poses.csv")))
    return rows[0], rows[1:]


def write_case(folder: Path, data_rows) -> Path:
    header, _ = demo_rows()
    folder.mkdir(exist_ok=True)
    with open(folder / "data.csv", "w", newline="") as f:
        csv.writer(f).writerows([header] + list(data_rows))
    (folder / "calib.yaml").write_text(OFFSETS)
    return folder / "calib.yaml"


def test_free_parameters_of_the_offsets_config(tmp_path):
    """The boundary below is set by this count: base (6) + the 6 joint offsets."""
    _, rows = demo_rows()
    assert len(load_config(write_case(tmp_path, rows[:12])).problem.params.free_names) == 12


@pytest.mark.parametrize("distinct, refused", [(2, True), (3, False)])
def test_distinct_postures_must_outnumber_the_free_parameters(tmp_path, distinct, refused):
    """60 rows of `distinct` postures (each written 60 / distinct times): a pose gives 6 rows per posture, so 2
    postures give 12 rows for 12 free parameters - an exact fit whose repeats would fake a noise estimate:
    refused, naming the counts; 3 postures give 18 > 12: a note, and the fit may go on."""
    _, rows = demo_rows()
    setup = load_config(write_case(tmp_path, rows[:distinct] * (60 // distinct)))
    if refused:
        with pytest.raises(InputError) as exc:
            check_inputs(setup)
        message = str(exc.value)
        assert "60 rows hold 2 distinct postures (58 repeat an earlier posture)" in message
        assert "12 measurement rows cannot determine 12 free parameters" in message
        assert exc.value.source.endswith("data.csv")
    else:
        (note,) = check_inputs(setup)
        assert note.startswith("note: ") and "60 rows at 3 distinct postures" in note
        assert "57 rows copy an earlier row" in note and "rows 5, 6, 7, 8, 9, 10, 11, 12 and 49 more" in note


def test_repeated_postures_give_the_fit_of_the_distinct_ones(tmp_path):
    """12 distinct postures each written 5 times fit to the same parameters as the 12 rows alone (the normal
    equations are 5 times those of the distinct rows). The standard errors shrink, by exactly
    sqrt((m - n) / (5 m - n)) for m = 72 rows of the distinct postures and n free parameters kept: what the
    note warns about ("the fit counts those measurements twice")."""
    _, rows = demo_rows()
    once = load_config(write_case(tmp_path / "once", rows[:12]))
    five = load_config(write_case(tmp_path / "five", rows[:12] * 5))
    counts = posture_counts(five)
    assert [(c.n_terms, c.n_distinct, len(c.copied_rows), c.distinct_rows) for c in counts] == [(60, 12, 48, 72)]
    assert check_inputs(once) == [] and "48 rows copy an earlier row" in check_inputs(five)[0]
    a, b = calibrate(once.problem, once.options), calibrate(five.problem, five.options)
    assert a.solve.success and b.solve.success and a.params.free_names == b.params.free_names
    names = a.params.free_names
    va, vb = (np.array([r.params[n].value for n in names]) for r in (a, b))
    # both converge from the same start on the same normal equations: agreement to the solver's tolerance,
    # far below the parameters' standard errors (~1e-5)
    assert np.allclose(va, vb, rtol=0, atol=1e-9), np.abs(va - vb).max()
    m, n = 72, len(names)
    ratio = np.array([b.params[x].stderr / a.params[x].stderr for x in names])
    assert np.allclose(ratio, np.sqrt((m - n) / (5 * m - n)), rtol=1e-6)


def test_a_posture_rounded_differently_is_the_same_posture(tmp_path):
    """Readings written again with fewer digits (1e-9 rad apart) are one posture; 1e-4 rad apart are two."""
    header, rows = demo_rows()
    near = [row[:] for row in rows[:2]]
    far = [row[:] for row in rows[:2]]
    for row in near:
        row[0] = repr(float(row[0]) + 1e-9)
    for row in far:
        row[0] = repr(float(row[0]) + 1e-4)
    (near_count,) = posture_counts(load_config(write_case(tmp_path / "near", rows[:12] + near)))
    assert near_count.n_distinct == 12 and near_count.copied_rows == [14, 15]
    assert posture_counts(load_config(write_case(tmp_path / "far", rows[:12] + far)))[0].n_distinct == 14


@pytest.mark.parametrize("config", [DEMO / "ur5_calibrate.yaml",
                                    *sorted(Path(p) for p in glob.glob(str(ROOT / "examples/tiago_mocap/*.yaml"))
                                            if "protocol" not in p)], ids=lambda p: p.stem)
def test_the_shipped_examples_pass_every_check_silently(config):
    """No finding, no note on the shipped data: the TIAGo's torso reads 0.2 mm past its upper limit, well
    inside the 10 % margin (35 mm); its points start at their frame's origin (spread ratios 1.15, 1.25)."""
    assert check_inputs(load_config(config)) == []


def test_a_look_alike_column_name_is_said(tmp_path):
    """A zero-width space after a column name prints like the name: the missing-column error says so."""
    (tmp_path / "t.csv").write_text("a\u200b,b\n1,2\n", encoding="utf-8")
    with pytest.raises(InputError, match=re.escape("the column 'a\\u200b' looks the same but holds invisible")):
        read_csv(tmp_path / "t.csv").column("a")
