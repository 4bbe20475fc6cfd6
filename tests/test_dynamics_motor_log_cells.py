"""robocal.dynamics.motor_log reads its blocks with numpy's parser and falls back to the checked, cell-by-cell
path on any doubt: the same numbers as Python's float(), and a bad cell still named by file, row and column."""
import numpy as np
import pytest

from robocal.dynamics.motor_log import load_motor_log
from robocal.errors import InputError

MOTORS = ["m1", "m2"]


def write_log(path, cells):
    rows = ["t,m1_position,m2_position,m1_effort,m2_effort"] + [",".join(r) for r in cells]
    path.write_text("\n".join(rows) + "\n")
    return {"position": str(path), "effort": str(path)}


def read(files, block=16):
    # 100 Hz, below max_rate_hz: no reduction, every row kept as read
    return load_motor_log(files, MOTORS, MOTORS, "t", max_rate_hz=250.0, block=block)


def cells(n=50):
    rng = np.random.default_rng(3)
    return [[repr(0.01 * k)] + [repr(float(v)) for v in rng.normal(size=4) * 10.0 ** rng.integers(-8, 8, 4)]
            for k in range(n)]


def test_numbers_are_pythons_float_of_each_cell(tmp_path):
    rows = cells()
    rows[7][2] = f'" {rows[7][2]} "'            # quoted, with spaces: float() reads it
    log = read(write_log(tmp_path / "a.csv", rows))
    expect = np.array([[float(c.strip('" ')) for c in r] for r in rows])
    assert np.array_equal(log.t, expect[:, 0])
    assert np.array_equal(np.c_[log.position, log.effort_raw], expect[:, 1:])


@pytest.mark.parametrize("bad", ["abc", "nan", "inf", ""])
def test_a_bad_cell_is_named_by_row_and_column(tmp_path, bad):
    rows = cells()
    rows[37][3] = bad                           # data row 37: line 39, in the third block of 16
    with pytest.raises(InputError, match="not a finite number") as info:
        read(write_log(tmp_path / "b.csv", rows))
    assert (info.value.row, info.value.field) == (39, "effort:m1")


def test_a_blank_line_is_refused_not_skipped(tmp_path):
    files = write_log(tmp_path / "c.csv", cells())
    text = open(files["position"]).read().split("\n")
    text.insert(21, "")                          # after data row 19: line 22 is empty
    open(files["position"], "w").write("\n".join(text))
    with pytest.raises(InputError) as info:
        read(files)
    assert info.value.row == 22
