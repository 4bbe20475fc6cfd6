"""Each source machine's page shows the tables its example prints (docs/architecture.md, "Docs from examples").

Every example registered in scripts/docs_from_examples.py takes --check-docs: it computes its tables as it would print them and compares
them with the generated blocks of its page (robocal.io.doc_blocks.page_differences: same text, numbers
within one unit of their last printed digit), exiting 1 with the differences. The fast examples recompute
everything; the Stewart example (2 min of one core) recomputes a sample of the runs its page was rendered
from (docs/data/stewart_calibration_runs.json) and re-renders the page from all of them.
"""
import importlib.util
from pathlib import Path

import pytest

from robocal.errors import InputError
from robocal.io.doc_blocks import begin_marker, end_marker, page_differences, read_block, replace_block, same_figures

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("docs_from_examples", ROOT / "scripts" / "docs_from_examples.py")
registry = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(registry)


@pytest.mark.parametrize("command", registry.EXAMPLES, ids=lambda c: Path(c[0]).stem)
def test_the_page_shows_what_the_example_prints(command):
    run = registry.run(command, "--check-docs")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]


PAGE = """intro
<!-- generated: table, by python x.py; do not edit, run the command with --write-docs -->
| a | 0.0091 | 2.3e-05 |
<!-- end generated: table -->
outro
"""


def test_blocks_are_read_and_replaced_between_their_markers(tmp_path):
    assert read_block(PAGE, "table") == "| a | 0.0091 | 2.3e-05 |\n"
    new = replace_block(PAGE, "table", "| b |", "python y.py")
    assert new.startswith("intro\n" + begin_marker("table", "python y.py") + "\n| b |\n" + end_marker("table"))
    assert new.endswith("outro\n")
    page = tmp_path / "page.md"
    page.write_text(PAGE)
    assert page_differences(page, {"table": "| a | 0.0091 | 2.3e-05 |"}) == []
    assert page_differences(page, {"table": "| a | 0.0093 | 2.3e-05 |"}) == [
        "page.md, block 'table': page shows 0.0091, example prints 0.0093"]
    with pytest.raises(InputError, match="exactly one generated block 'other'"):
        page_differences(page, {"other": "x"})


def test_numbers_may_differ_by_one_unit_of_their_last_printed_digit_and_nothing_else():
    assert same_figures("| 0.0091 | 2.3e-05 | -0.00 |", "| 0.0092 | 2.4e-05 | +0.00 |") == []
    assert same_figures("| 0.0091 |", "| 0.0094 |") == ["page shows 0.0091, example prints 0.0094"]
    assert same_figures("| 2.3e-05 |", "| 2.5e-05 |") == ["page shows 2.3e-05, example prints 2.5e-05"]
    assert same_figures("| 7 iterations |", "| 7 steps |")[0].startswith("line 1 differs")
