"""robocal.dynamics.log_loading.numeric_table: the joint logs' fast reader gives io.tables' numbers exactly, and
leaves every file it cannot vouch for to io.tables (which names the fault)."""
import numpy as np
import pytest

from robocal.dynamics.log_loading import numeric_table
from robocal.io.tables import read_csv


def write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


def test_same_numbers_as_io_tables(tmp_path):
    rng = np.random.default_rng(5)
    values = rng.normal(size=(40, 3)) * 10.0 ** rng.integers(-9, 9, (40, 3))
    f = write(tmp_path / "a.csv", "t,- j_position,x\n" + "".join(",".join(repr(float(v)) for v in r) + "\n"
                                                                for r in values))
    fast, table = numeric_table(f), read_csv(f)
    assert fast.header == table.header and fast.n_rows == table.n_rows
    for name in table.header:
        assert np.array_equal(fast.column(name), table.column(name))


@pytest.mark.parametrize("text", ["\ufefft,a\n0,1\n1,2\n",        # byte-order mark: io.tables strips and notes it
                                  "t,a\n0,1\n1,abc\n",            # not a number
                                  "t,a\n0,1\n1,nan\n",            # not finite
                                  "t,a\n0,1\n1,2,3\n",            # a row of another length
                                  "t,t\n0,1\n1,2\n",              # duplicate names
                                  "t,a\n"])                       # no rows
def test_anything_doubtful_goes_to_io_tables(tmp_path, text):
    assert numeric_table(write(tmp_path / "b.csv", text)) is None
    assert numeric_table(tmp_path / "missing.csv") is None


def test_a_missing_column_gets_io_tables_error(tmp_path):
    from robocal.errors import InputError
    with pytest.raises(InputError, match="missing column") as info:
        numeric_table(write(tmp_path / "c.csv", "t,a\n0,1\n1,2\n")).column("b")
    assert info.value.field == "b"
