"""The pytest plugin: its fixtures and options in a small suite (pytester), and the example CI suite
in examples/ci_suite run by a pytest subprocess, with and without a dataset."""
import os
import subprocess
import sys
from importlib.metadata import entry_points
from importlib.resources import files
from pathlib import Path

import pytest

# Imported here, before any in-process pytester run: pytester drops the modules a run imported, and
# numpy's C extensions (pulled in by scipy) cannot be loaded twice in one process.
from robocal.estimation.calibrate import calibrate
from robocal.workflows.setup import load_config
from robocal.model.urdf_export import export_urdf
import robocal.testing  # noqa: F401  (scipy.stats)

pytest_plugins = ["pytester"]

ROOT = Path(__file__).resolve().parents[1]
DEMO = Path(str(files("robocal.io") / "demo" / "ur5_calibrate.yaml"))


def plugin_args() -> list[str]:
    """`-p robocal.testing.pytest_plugin` unless the `robocal` pytest11 entry point already loads it
    (giving both would register the module twice)."""
    installed = any(ep.name == "robocal" for ep in entry_points(group="pytest11"))
    if installed and not os.environ.get("PYTEST_DISABLE_PLUGIN_AUTOLOAD"):
        return []
    return ["-p", "robocal.testing.pytest_plugin"]


SUITE = """
import numpy as np
import pytest

def test_seed(robocal_seed):
    assert robocal_seed == EXPECTED_SEED

def test_factory_is_seeded(robocal_synthetic, robocal_seed):
    a, b = robocal_synthetic("ur5", n_samples=4), robocal_synthetic("ur5", n_samples=4, seed=robocal_seed)
    assert a.seed == robocal_seed
    np.testing.assert_array_equal(a.problem.values, b.problem.values)
    c = robocal_synthetic("ur5", n_samples=4, seed=robocal_seed + 1)
    assert not np.array_equal(a.problem.values, c.problem.values)

@pytest.mark.robocal_robot("ur5")
def test_marker_robot(robocal_robot):
    assert robocal_robot.name == "ur5" and robocal_robot.model.existFrame("tool0")

def test_option_robot(robocal_robot):
    assert robocal_robot.name == "panda"

def test_loader(robocal_load_robot):
    assert robocal_load_robot("ur5").model.nq == 6

def test_dataset(robocal_dataset, robocal_setup, robocal_urdf):
    assert robocal_dataset.name == "ur5_calibrate.yaml" and robocal_urdf is None
    assert [r.name for r in robocal_setup.problem.residuals] == ["tracker"]
    assert len(robocal_setup.problem.values) == 60
"""


def test_fixtures_and_options_in_a_small_suite(pytester):
    pytester.makepyfile(test_user=SUITE.replace("EXPECTED_SEED", "7"))
    result = pytester.runpytest(*plugin_args(), "--robocal-seed", "7", "--robocal-robot", "panda",
                                "--robocal-dataset", str(DEMO), "-p", "no:cacheprovider")
    result.assert_outcomes(passed=6)


def test_without_options_the_dataset_and_robot_tests_are_skipped(pytester):
    pytester.makepyfile(test_user=SUITE.replace("EXPECTED_SEED", "0"))
    result = pytester.runpytest(*plugin_args(), "-rs", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=4, skipped=2)
    result.stdout.fnmatch_lines(["*no robot given (@pytest.mark.robocal_robot(name) or --robocal-robot)*",
                                 "*no dataset given (--robocal-dataset PATH)*"])


def test_a_missing_dataset_file_is_a_usage_error(pytester):
    pytester.makepyfile(test_user="def test_d(robocal_dataset):\n    pass\n")
    result = pytester.runpytest(*plugin_args(), "--robocal-dataset", "nowhere.yaml", "-p", "no:cacheprovider")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*--robocal-dataset*nowhere.yaml: file not found*"])


def _run_example_suite(*options):
    env = dict(os.environ, OMP_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "pytest", str(ROOT / "examples" / "ci_suite"), *plugin_args(), "-rs",
           "-p", "no:cacheprovider", *options]
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def calibrated_urdf(tmp_path_factory):
    """The demo's calibrated URDF, written by robocal's exporter."""
    setup = load_config(DEMO)
    result = calibrate(setup.problem, setup.options)
    return export_urdf(setup.robot, result.params, tmp_path_factory.mktemp("ci") / "ur5_calibrated.urdf")


def test_example_suite_without_a_dataset_passes_and_skips_the_dataset_check():
    run = _run_example_suite()
    assert run.returncode == 0, run.stdout + run.stderr
    assert "4 passed, 1 skipped" in run.stdout


def test_example_suite_passes_with_the_calibrated_urdf_and_fails_with_the_nominal(calibrated_urdf):
    good = _run_example_suite("--robocal-dataset", str(DEMO), "--robocal-urdf", str(calibrated_urdf))
    assert good.returncode == 0, good.stdout + good.stderr
    assert "5 passed" in good.stdout
    drifted = _run_example_suite("--robocal-dataset", str(DEMO))
    assert drifted.returncode == 1, drifted.stdout + drifted.stderr
    assert "1 failed, 4 passed" in drifted.stdout
    assert "block 'tracker' (pose, 360 rows): RMS" in drifted.stdout
