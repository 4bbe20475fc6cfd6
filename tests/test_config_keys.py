"""Strict config: the one key schema (robocal/io/config_keys.py) against docs/config.md and the parsers."""
import re
from pathlib import Path

import pytest
import yaml

from robocal.errors import InputError
from robocal.workflows.setup import load_config, setup_from_config
from robocal.workflows.config_keys import PYTHON_ONLY_TYPES, SCHEMA, all_key_names, check_keys
from robocal.residuals import REGISTRY

DOCS = (Path(__file__).parents[1] / "docs" / "config.md").read_text()
DEMO = Path(__file__).parents[1] / "robocal" / "io" / "demo" / "ur5_calibrate.yaml"


def test_docs_name_every_key_the_code_accepts():
    missing = sorted(k for k in all_key_names() if not re.search(rf"\b{re.escape(k)}\b", DOCS))
    assert not missing, f"docs/config.md does not mention: {missing}"


def test_docs_name_every_measurement_type():
    missing = [t for t in REGISTRY if f"`{t}`" not in DOCS and f"type: {t}" not in DOCS]
    assert not missing
    for t in PYTHON_ONLY_TYPES:
        assert re.search(rf"`{t}`.*Python only", DOCS)


@pytest.mark.parametrize("path, key, suggestion", [
    ("measurements[0].sigma", "positon", "position"),
    ("simulation", "sedd", "seed"),
    ("simulation.perturb", "rotaton", "rotation"),
    ("plan", "criterium", "criterion"),
    ("plan.volume.sphere", "centre", "center"),
    ("plan.output", "dri", "dir"),
    ("iso9283", "comanded", "commanded"),
    ("output", "reprot", "report"),
    ("solver", "max_iteration", "max_iterations"),
    ("data.joint_units", "angel", "angle"),
    ("robot.base", "xzy", "xyz"),
    ("measurements[0]", "wieghts", "weights"),
])
def test_a_misspelt_key_anywhere_is_named_with_its_path_and_the_nearest_key(path, key, suggestion):
    raw = yaml.safe_load(DEMO.read_text())
    node = raw
    for part in path.split("."):
        name, _, index = part.partition("[")
        node = node.setdefault(name, {})
        if index:
            node = node[int(index[:-1])]
    node[key] = 1
    with pytest.raises(InputError) as exc:
        check_keys(raw, "calib.yaml")
    assert exc.value.field == f"{path}.{key}" and f"did you mean '{suggestion}'" in str(exc.value)


def test_the_setup_checks_the_whole_document_before_reading_data(tmp_path):
    """A misspelt plan/iso9283 key stops `robocal calibrate` too (before the old code ignored those sections)."""
    raw = yaml.safe_load(DEMO.read_text())
    raw["iso9283"] = {"pose_id": "pose", "distance_pair": []}
    with pytest.raises(InputError, match="did you mean 'distance_pairs'"):
        setup_from_config(raw, DEMO.parent, str(DEMO))


def test_every_schema_section_is_a_top_key():
    assert set(SCHEMA) == {"robot", "data", "parameters", "measurements", "solver", "output", "simulation", "plan",
                           "iso9283"}
    assert load_config(DEMO).problem.residuals[0].name == "tracker"
