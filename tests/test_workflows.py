"""The workflow layer: one typed config read once, one calibration path shared by the command line, the
fleet's units and Python."""
import dataclasses

import pytest
import yaml

from robocal.cli.main import main
from robocal.workflows import parse_config, read_config
from robocal.workflows.config_types import CalibrationConfig

pytest.importorskip("pyarrow")   # the fleet's table: the [fleet] extra (the [test] extra installs it)

from robocal.workflows.fleet.manifest import load_fleet  # noqa: E402
from robocal.workflows.fleet.synthetic import simulated_fleet  # noqa: E402
from robocal.workflows.fleet.unit import calibrate_unit, unit_config  # noqa: E402


def test_a_fleet_unit_writes_the_folder_robocal_calibrate_writes(tmp_path):
    fleet = simulated_fleet(tmp_path / "fleet", n_units=1, samples=20)
    job = load_fleet(fleet.fleet_yaml).jobs[0]
    row = calibrate_unit(job)
    assert row["status"] == "converged", row["message"]
    config = tmp_path / "unit.yaml"
    config.write_text(yaml.safe_dump(unit_config(job).to_dict(), sort_keys=False))
    by_hand = tmp_path / "by_hand"
    assert main(["calibrate", str(config), "-o", str(by_hand), "-q"]) == 0
    fleet_dir = tmp_path / "fleet" / "fleet-output" / "units" / job.key
    names = sorted(p.name for p in fleet_dir.iterdir())
    assert names == sorted(p.name for p in by_hand.iterdir())
    assert {"config.yaml", "result.json", "scene.json", "summary.txt"} <= set(names)
    assert any(n.endswith("_calibrated.urdf") for n in names)
    for name in names:
        if name != ".robocal-manifest.json":
            assert (fleet_dir / name).read_bytes() == (by_hand / name).read_bytes(), name


def test_config_reads_back_from_its_own_dict(tmp_path):
    """to_dict() is what calibrate writes as config.yaml: parsing it gives the same typed config."""
    fleet = simulated_fleet(tmp_path, n_units=1, samples=5)
    config = read_config(fleet.template)
    again = parse_config(config.to_dict(), tmp_path / "elsewhere", "config.yaml")
    assert isinstance(again, CalibrationConfig)
    assert dataclasses.replace(again, source=config.source, base_dir=config.base_dir) == config
