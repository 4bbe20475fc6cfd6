"""pytest plugin: fixtures and options for checking robot models in a project's own test suite.

Loaded through the `pytest11` entry point `robocal` (or `pytest -p robocal.testing.pytest_plugin`).

Options
  --robocal-dataset PATH   a calibration YAML whose robot and measurements the suite checks
  --robocal-urdf PATH      a (calibrated) URDF to check against that dataset
  --robocal-robot NAME     a robot for the `robocal_robot` fixture: URDF path or example name
  --robocal-seed N         seed of the synthetic factory (default 0)

Fixtures
  robocal_dataset          Path of --robocal-dataset (the test is skipped when it is not given)
  robocal_setup            robocal.workflows.setup.Setup of that dataset (robot from --robocal-urdf if given)
  robocal_urdf             Path of --robocal-urdf, or None
  robocal_robot            Robot from @pytest.mark.robocal_robot("ur5" | path) or --robocal-robot
  robocal_load_robot       function: URDF path or example name -> Robot
  robocal_seed             the seed (int)
  robocal_synthetic        factory: robocal_synthetic(robot="ur5", n_samples=40, seed=None, ...) ->
                           robocal.testing.assertions.SyntheticCase (seed defaults to robocal_seed)
"""
from __future__ import annotations

from pathlib import Path

import pytest
from robocal.testing.assertions import dataset_setup
from robocal.testing.assertions import load_robot
from robocal.testing.assertions import synthetic_pose_case


def pytest_addoption(parser):
    group = parser.getgroup("robocal", "robot model checks (robocal)")
    group.addoption("--robocal-dataset", metavar="PATH", default=None,
                    help="calibration YAML whose measurements the robocal fixtures load")
    group.addoption("--robocal-urdf", metavar="PATH", default=None,
                    help="URDF (e.g. a calibrated one) to check against --robocal-dataset")
    group.addoption("--robocal-robot", metavar="NAME", default=None,
                    help="URDF path or example name for the robocal_robot fixture")
    group.addoption("--robocal-seed", metavar="N", type=int, default=0,
                    help="seed of the robocal_synthetic factory (default 0)")


def pytest_configure(config):
    config.addinivalue_line("markers", "robocal_robot(name_or_path): robot loaded by the robocal_robot fixture")


def pytest_report_header(config):
    ds = config.getoption("--robocal-dataset", None)
    return f"robocal dataset: {ds}" if ds else None


def _path_option(config, name: str):
    value = config.getoption(name)
    if value is None:
        return None
    path = Path(value)
    if not path.is_absolute():
        path = Path(config.invocation_params.dir) / path
    return path.resolve()


@pytest.fixture
def robocal_dataset(request) -> Path:
    path = _path_option(request.config, "--robocal-dataset")
    if path is None:
        pytest.skip("no dataset given (--robocal-dataset PATH)")
    if not path.is_file():
        raise pytest.UsageError(f"--robocal-dataset {path}: file not found")
    return path


@pytest.fixture
def robocal_urdf(request):
    path = _path_option(request.config, "--robocal-urdf")
    if path is not None and not path.is_file():
        raise pytest.UsageError(f"--robocal-urdf {path}: file not found")
    return path


@pytest.fixture
def robocal_setup(robocal_dataset, robocal_urdf):
    """A fresh Setup per test (calibrating changes its parameters)."""
    return dataset_setup(robocal_dataset, robocal_urdf)


@pytest.fixture(scope="session")
def robocal_load_robot():
    return load_robot


@pytest.fixture
def robocal_robot(request, robocal_load_robot):
    marker = request.node.get_closest_marker("robocal_robot")
    name = marker.args[0] if marker and marker.args else request.config.getoption("--robocal-robot")
    if name is None:
        pytest.skip("no robot given (@pytest.mark.robocal_robot(name) or --robocal-robot)")
    return robocal_load_robot(name)


@pytest.fixture
def robocal_seed(request) -> int:
    return int(request.config.getoption("--robocal-seed"))


@pytest.fixture
def robocal_synthetic(robocal_seed):

    def make(robot="ur5", n_samples: int = 40, seed: int | None = None, **kwargs):
        return synthetic_pose_case(robot, n_samples, robocal_seed if seed is None else seed, **kwargs)

    return make
