"""`robocal calibrate` on the closed-loop examples described in MJCF (examples/closed_loops/): the Stewart
platform and the crank-rocker four-bar, end to end from the config, against the truth their data were made from.
Also the config's `robot: mjcf:` errors."""
import json
import shutil
from pathlib import Path

import pytest

from robocal.cli.main import main
from robocal.errors import InputError
from robocal.workflows.setup import load_config

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "closed_loops"


def copy_example(tmp_path, *names):
    for name in names:
        shutil.copy(EXAMPLES / name, tmp_path / name)
    return tmp_path


@pytest.mark.parametrize("config, files, truth_file, rename", [
    ("stewart_calibrate.yaml", ["stewart_6_6.xml", "stewart_poses.csv"], "stewart_poses_truth.json",
     {"slide.offset": "slide.tz"}),     # the config fits o_j as the slide's placement along its axis
    ("fourbar_calibrate.yaml", ["fourbar.xml", "fourbar_points.csv"], "fourbar_points_truth.json", {}),
])
def test_mjcf_examples_calibrate_from_the_command_line(tmp_path, capsys, config, files, truth_file, rename):
    """Exit code 0, result.json and no calibrated URDF (an MJCF robot has none to edit); every fitted parameter
    within 4 standard errors of the truth the data were simulated from (noise 10 um: make_stewart_data.py,
    10 um on the four-bar's pen), which a correct fit misses with a chance of ~1e-4 per parameter."""
    folder = copy_example(tmp_path, config, *files, truth_file)
    assert main(["calibrate", str(folder / config), "-q"]) == 0
    out = folder / load_config(folder / config).output_dir.name
    assert sorted(p.name for p in out.iterdir() if p.suffix == ".urdf") == []
    fitted = {p["name"]: p for p in json.loads((out / "result.json").read_text())["parameters"]}
    truth = json.loads((folder / truth_file).read_text())["parameters"]
    checked = 0
    for name, value in truth.items():
        for old, new in rename.items():
            name = name.replace(old, new)
        p = fitted.get(name)
        if p is None or not p.get("stderr"):
            continue
        assert abs(p["value"] - value) < 4 * p["stderr"], (name, p["value"], value, p["stderr"])
        checked += 1
    assert checked >= 10


def test_config_mjcf_errors_name_the_file(tmp_path):
    folder = copy_example(tmp_path, "fourbar_calibrate.yaml", "fourbar.xml", "fourbar_points.csv")
    text = (folder / "fourbar_calibrate.yaml").read_text()
    both = folder / "both.yaml"
    both.write_text(text.replace("  mjcf: fourbar.xml", "  mjcf: fourbar.xml\n  urdf: fourbar.urdf"))
    with pytest.raises(InputError, match="exactly one of 'urdf'"):
        load_config(both)
    stray = folder / "stray.yaml"
    stray.write_text(text.replace("  mjcf: fourbar.xml", "  mjcf: fourbar.xml\n  actuated: [elbow]"))
    with pytest.raises(InputError, match="actuated joint 'elbow' is not a joint of the model") as info:
        load_config(stray)
    assert info.value.source == str(folder / "fourbar.xml")
    (folder / "fourbar.xml").write_text((folder / "fourbar.xml").read_text().replace('body2="rocker_link"',
                                                                                     'body2="rocker"'))
    with pytest.raises(InputError, match="names body 'rocker' in body2, which is not in the model") as info:
        load_config(folder / "fourbar_calibrate.yaml")
    assert info.value.source == str(folder / "fourbar.xml") and info.value.row is not None


def test_presets_over_passive_joints(tmp_path):
    """`preset: full` over a four-bar whose coupler and rocker joints are solved by its loop: offsets only
    on the read joint (a passive joint's zero is its placement's rz, a convention of the loop), and the fit
    runs; compliance named on a passive joint is refused with the key."""
    folder = copy_example(tmp_path, "fourbar_calibrate.yaml", "fourbar.xml", "fourbar_points.csv")
    config = folder / "fourbar_calibrate.yaml"
    text = config.read_text()
    config.write_text(text.replace("preset: placements ", "preset: full "))
    setup = load_config(config)
    offsets = [p.name for p in setup.problem.params if p.kind == "joint_offset"]
    assert offsets == ["crank.offset"]
    assert main(["calibrate", str(config), "-q", "--no-report", "-o", str(tmp_path / "full")]) == 0
    config.write_text(text.replace("preset: placements ", "preset: placements\n  compliance: [rocker]\n "))
    with pytest.raises(InputError) as err:
        load_config(config)
    assert err.value.field == "parameters.compliance" and "'rocker'" in str(err.value)
