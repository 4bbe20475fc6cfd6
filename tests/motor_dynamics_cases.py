"""The motor-side examples (examples/motor_dynamics/: a UR5 with joint 6 driven by motors 5 and 6, a TIAGo arm
with a differential wrist) written by their own script into a temporary folder, with the truth they were made
of, for tests/test_dynamics_motor_side.py and tests/test_dynamics_motor_bad_input.py."""
from __future__ import annotations

import importlib.util
import shutil
import sys
from pathlib import Path

import numpy as np

from robocal.dynamics.identification import base_values_of
from robocal.dynamics.inertial import parameter_vector

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "motor_dynamics"
CASES = ("ur5_coupled", "tiago_wrist")


def make_logs():
    """examples/motor_dynamics/make_logs.py as a module (the script the user runs)."""
    if "motor_make_logs" not in sys.modules:        # registered: its dataclasses look their module up
        spec = importlib.util.spec_from_file_location("motor_make_logs", EXAMPLE / "make_logs.py")
        sys.modules["motor_make_logs"] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sys.modules["motor_make_logs"])
    return sys.modules["motor_make_logs"]


def write_case(case: str, folder: Path, seconds: float | None = None):
    """The case's configs copied into `folder`, its logs written into folder/data; (config path, truth)."""
    folder.mkdir(parents=True, exist_ok=True)
    for yaml_file in EXAMPLE.glob(f"{case}*.yaml"):
        shutil.copyfile(yaml_file, folder / yaml_file.name)
    script = make_logs()
    kwargs = {} if seconds is None else {"seconds": seconds}
    truth = script.write_case(case, folder / "data", config=folder / f"{case}.yaml", **kwargs)
    return folder / f"{case}.yaml", truth


def true_parameters(res, truth) -> np.ndarray:
    """[inertial, extra] of the truth in the identification's column order (the truth robot's bodies, the
    motors' terms of make_logs.TRUTH; the examples have no joint terms)."""
    motors = truth.config.transmission.motors
    extra = []
    for name in res.consistent_extra_names():
        owner, kind = name.rsplit(".", 1)
        extra.append(truth.motors.values(kind)[motors.index(owner)])
    return np.r_[parameter_vector(truth.robot), extra]


def base_z(res, truth) -> np.ndarray:
    """The OLS base parameters' distance from the truth's, in their standard errors."""
    return (res.ols.values - base_values_of(res.ols.selection, true_parameters(res, truth))) / res.ols.std
