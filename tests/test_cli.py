"""The robocal command: demo, simulate -> calibrate round trip, output folder contents."""
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from robocal.cli.main import build_parser, main

DEMO = Path(__file__).parents[1] / "robocal" / "io" / "demo"


def test_demo_writes_urdf_json_and_summary(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out), "-q"]) == 0
    files = sorted(p.name for p in out.iterdir())
    assert files == [".robocal-manifest.json", "config.yaml", "report.html", "result.json", "scene.json", "summary.txt",
                     "ur5_robot_calibrated.urdf"]
    result = json.loads((out / "result.json").read_text())
    ident = result["identifiability"]
    assert result["success"] and ident["identifiable_from_data"] == 30
    # one partition of the 54 requested parameters, the same counts as the statements say
    assert ident["counts"] == {"determined": 30, "weakly determined": 0, "loose": 0, "set by the prior": 0, "fixed": 24}
    assert ident["statements"][0].startswith("Of 54 requested parameters, 30 are identifiable from the data alone: "
                                             "30 determined")
    by_name = {p["name"]: p for p in result["parameters"]}
    assert by_name["wrist_2_joint.offset"]["identifiable"] is True
    assert by_name["wrist_2_joint.offset"]["stderr"] > 0
    assert by_name["shoulder_pan_joint.rz"]["identifiable"] is False
    # the measurement frame comes first in the order, so it absorbs the base joint's rotation and offset
    assert by_name["shoulder_pan_joint.rz"]["confounded_with"][0][0] == "base.rz"
    assert by_name["shoulder_pan_joint.offset"]["identifiable"] is False
    text = capsys.readouterr().out
    assert "RMS before" in text and "mm" in text and "mrad" in text


def test_demo_model_matches_the_shipped_truth_on_new_poses(tmp_path):
    """The calibrated model predicts the true robot's flange on unseen poses to what the noise allows."""
    from robocal import load_example
    from robocal.model.kinematics import ModelState
    from robocal.model.parameters import robot_parameters
    from robocal.design.simulate import random_configurations

    out = tmp_path / "demo"
    main(["demo", "-o", str(out), "-q"])
    est = {p["name"]: p["value"] for p in json.loads((out / "result.json").read_text())["parameters"]}
    truth = json.loads((DEMO / "ur5_tracker_poses_truth.json").read_text())["parameters"]
    robot = load_example("ur5")
    joints = robot.joint_names
    fitted = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True).set_values(est)
    true = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True).set_values(truth)
    nominal = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True)
    configs = random_configurations(robot, joints, 50, np.random.default_rng(0))
    a, b, c = (ModelState(robot, p, joints) for p in (fitted, true, nominal))
    err = np.array([np.linalg.norm(a.sample(q).pose("tool0").translation - b.sample(q).pose("tool0").translation)
                    for q in configs])
    before = np.array([np.linalg.norm(c.sample(q).pose("tool0").translation - b.sample(q).pose("tool0").translation)
                       for q in configs])
    # 30 parameters from 360 rows at sigma 50 um: prediction error ~ 50 um * sqrt(30 / 360) ~ 15 um RMS
    # per axis; 100 um is over 6 such deviations on the 3D norm. Before calibration it is millimetres.
    assert err.max() < 100e-6
    assert before.mean() > 1e-3


def test_simulate_then_calibrate_round_trip(tmp_path):
    for f in ("ur5_calibrate.yaml",):
        shutil.copy(DEMO / f, tmp_path / f)
    assert main(["simulate", str(tmp_path / "ur5_calibrate.yaml")]) == 0
    a = np.loadtxt(tmp_path / "ur5_tracker_poses.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(DEMO / "ur5_tracker_poses.csv", delimiter=",", skiprows=1)
    assert np.array_equal(a, b)   # deterministic: the shipped demo data is what `simulate` writes
    assert main(["calibrate", str(tmp_path / "ur5_calibrate.yaml"), "-q"]) == 0
    assert (tmp_path / "robocal-output" / "result.json").is_file()
    # a second run refuses to overwrite unless asked
    assert main(["calibrate", str(tmp_path / "ur5_calibrate.yaml"), "-q"]) == 2
    assert main(["calibrate", str(tmp_path / "ur5_calibrate.yaml"), "-q", "--force"]) == 0


def test_simulate_contact_blocks_and_calibrate(tmp_path):
    cfg = tmp_path / "contact.yaml"
    cfg.write_text("""
robot: {example: ur5, frames: [{name: probe, parent: tool0, xyz: [0.01, 0.02, 0.12]}]}
data: {csv: touches.csv}
parameters: {preset: offsets}
measurements:
  - {type: plane, name: table, frame: probe, normal: [0, 0, 1], offset: 0.05, tip_radius: 0.003,
     sigma: 1.0e-5, where: {block: 0}, samples: 40}
  - {type: sphere, name: ball, frame: probe, centre: [0.4, 0.2, 0.3], radius: 0.0125, tip_radius: 0.003,
     sigma: 1.0e-5, where: {block: 1}, samples: 40}
simulation: {seed: 3, perturb: {translation: 0.0, rotation: 0.003}}
""")
    assert main(["simulate", str(cfg)]) == 0
    assert main(["calibrate", str(cfg), "-q"]) == 0
    res = json.loads((tmp_path / "robocal-output" / "result.json").read_text())
    truth = json.loads((tmp_path / "touches_truth.json").read_text())["parameters"]
    est = {p["name"]: p for p in res["parameters"]}
    for name, p in est.items():
        if p["identifiable"] and name.endswith(".offset") and "joint" in name and name != "table.offset":
            # truth perturbs every offset; identifiable ones that nothing absorbs match within 5 sigma
            assert abs(p["value"] - truth[name]) < 5 * p["stderr"] + 1e-9, name


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.startswith("robocal ")


def test_view_of_a_missing_folder_says_so_plainly(tmp_path, capsys):
    assert main(["view", str(tmp_path / "MISSING"), "--html", str(tmp_path / "v.html")]) == 2
    err = capsys.readouterr().err
    assert "MISSING: no such folder" in err and "re-run" not in err
    (tmp_path / "empty").mkdir()
    assert main(["view", str(tmp_path / "empty"), "--html", str(tmp_path / "v.html")]) == 2
    assert "no scene.json in this folder" in capsys.readouterr().err


def test_quiet_prints_only_the_summary_and_counts_are_singular(tmp_path, capsys):
    shutil.copy(DEMO / "ur5_calibrate.yaml", tmp_path / "c.yaml")
    shutil.copy(DEMO / "ur5_tracker_poses.csv", tmp_path / "ur5_tracker_poses.csv")
    assert main(["calibrate", str(tmp_path / "c.yaml"), "-q", "--no-report"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "RMS before" in captured.out and "Wrote" not in captured.out
    assert main(["simulate", str(tmp_path / "c.yaml"), "-q", "--force"]) == 0
    assert capsys.readouterr().out == ""
    # one sample: "1 sample", not "1 samples" (the fit then stops: too few rows)
    lines = (tmp_path / "ur5_tracker_poses.csv").read_text().splitlines()[:2]
    (tmp_path / "ur5_tracker_poses.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "c.yaml").write_text((tmp_path / "c.yaml").read_text().replace("preset: full", "preset: none")
                                     .replace("base: true", "base: false").replace("{tool0: true}", "{tool0: [tz]}"))
    main(["calibrate", str(tmp_path / "c.yaml"), "-o", str(tmp_path / "one"), "--no-report"])
    assert "1 sample, 1 measurement in 1 block, 1 free parameter" in capsys.readouterr().err


def test_every_argument_has_help_text():
    """Every option and positional of every command says what it is (`simulate --seed` and `config` did not)."""
    parser = build_parser()
    sub = next(a for a in parser._actions if a.choices)     # argparse keeps sub-parsers only there
    missing = [f"{name} {' '.join(a.option_strings) or a.dest}" for name, p in sub.choices.items()
               for a in p._actions if not a.help]
    assert not missing


def test_demo_twice_in_a_row_replaces_its_own_folder_but_not_a_foreign_one(tmp_path, monkeypatch):
    """The README's first command must pass when run again; the default folder is the demo's own."""
    monkeypatch.chdir(tmp_path)
    assert main(["demo", "--no-report", "-q"]) == 0
    assert main(["demo", "--no-report", "-q"]) == 0
    (tmp_path / "robocal-demo-output" / "notes.txt").write_text("mine")
    assert main(["demo", "--no-report", "-q"]) == 2          # a file robocal did not write: refused, kept
    assert (tmp_path / "robocal-demo-output" / "notes.txt").read_text() == "mine"


def test_a_fit_beyond_the_scene_limit_draws_a_subset_and_says_so(tmp_path, capsys, monkeypatch):
    import robocal.viz.scene as scene
    monkeypatch.setattr(scene, "MAX_SAMPLES", 5)          # the demo has more: as if it were a very large fit
    shutil.copy(DEMO / "ur5_calibrate.yaml", tmp_path / "c.yaml")
    shutil.copy(DEMO / "ur5_tracker_poses.csv", tmp_path / "ur5_tracker_poses.csv")
    out = tmp_path / "out"
    assert main(["calibrate", str(tmp_path / "c.yaml"), "-o", str(out)]) == 0
    assert "draws 5 of the" in capsys.readouterr().err
    drawn = json.loads((out / "scene.json").read_text())["drawn"]
    assert len(drawn["samples"]) == 5 and drawn["of"] > 5
    assert "5 of " in (out / "report.html").read_text() and (out / "result.json").is_file()
    assert main(["view", str(out), "--html", str(tmp_path / "v.html")]) == 0
    assert f"5 of {drawn['of']} samples drawn" in (tmp_path / "v.html").read_text()


def test_every_command_takes_quiet():
    from robocal.cli.main import build_parser, subcommands
    missing = [p.prog for p in subcommands(build_parser())
               if not any("--quiet" in a.option_strings for a in p._actions)]
    assert not missing, missing


def test_quiet_calibrate_prints_the_status_and_the_error_table_only(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path / "q"), "-q", "--no-report"]) == 0
    quiet = capsys.readouterr()
    assert main(["demo", "-o", str(tmp_path / "v"), "--no-report"]) == 0
    loud = capsys.readouterr()
    assert "Calibration converged" in quiet.out and "RMS after" in quiet.out
    assert "Estimated parameters" not in quiet.out and "Estimated parameters" in loud.out
    assert quiet.err == "" and len(quiet.out.splitlines()) < 12


def test_command_table_says_what_each_module_registers():
    """robocal.cli.main lists the commands it does not import by COMMANDS: names, modules and help lines must
    be what the modules themselves register (a command renamed or re-worded in its module fails here)."""
    from robocal.cli.main import COMMANDS
    sub = next(a for a in build_parser()._actions if a.choices)
    assert {a.dest: a.help for a in sub._choices_actions} == {n: h for n, (_, h) in COMMANDS.items()}
    for name, (module, _) in COMMANDS.items():
        one = next(a for a in build_parser([name, "x"])._actions if a.choices).choices[name]
        assert one._defaults.get("handler") or one._subparsers, name        # the module's parser, not a stub
        assert sub.choices[name].prog == one.prog


def test_version_imports_no_part_of_the_library():
    """`robocal --version` imports robocal.io (the version) and nothing above it, nor Pinocchio or scipy."""
    import subprocess
    import sys
    code = ("import sys\nfrom robocal.cli.main import main\ntry:\n    main(['--version'])\nexcept SystemExit:\n"
            "    pass\nprint(sorted(m for m in sys.modules if m.startswith(('robocal.', 'pinocchio', 'scipy'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    loaded = eval(out.strip().splitlines()[-1])
    assert "robocal.cli.main" in loaded
    assert all(m.split(".")[1] in ("cli", "errors", "io") for m in loaded if m.startswith("robocal.")), loaded
    assert not [m for m in loaded if m.startswith(("pinocchio", "scipy"))], loaded
    assert loaded.count("robocal.cli.main") == 1 and not [m for m in loaded if m.startswith("robocal.cli.") and
                                                           m != "robocal.cli.main"], loaded
