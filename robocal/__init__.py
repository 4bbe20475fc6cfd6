"""robocal: calibrate robot models (serial arms and parallel machines) described by URDF, MJCF or Pinocchio.

The names users call; docs/api.md lists them with the subpackages they come from.

Python runs this file before any module of robocal (`robocal.cli.main` for the `robocal` command,
`robocal.io.tables` for a script that reads one table), so it imports nothing itself: each name below is
imported from its module on first use (PEP 562), and `robocal --version` does not import the library.
Subpackages import what they export (tests/test_architecture.py); only this root and robocal.viz defer.
"""
from importlib import import_module

#: every public name and the module that defines it
EXPORTS = {
    "Robot": "robocal.model.robot", "load_urdf": "robocal.model.robot", "load_example": "robocal.model.robot",
    "load_mjcf": "robocal.model.mjcf", "robot_from_pinocchio": "robocal.model.pinocchio_robot",
    "Parameter": "robocal.model.parameters", "ParameterSet": "robocal.model.parameters",
    "robot_parameters": "robocal.model.parameters", "Setup": "robocal.workflows.setup",
    "load_config": "robocal.workflows.setup", "Problem": "robocal.estimation.problem",
    "CalibrationOptions": "robocal.estimation.calibrate", "calibrate": "robocal.estimation.calibrate",
    "CalibrationResult": "robocal.estimation.result", "evaluate_result": "robocal.workflows.evaluate",
    "write_results": "robocal.workflows.outputs", "export_urdf": "robocal.model.urdf_export",
    "perturb": "robocal.design.simulate", "random_configurations": "robocal.design.simulate",
    "simulate_measurements": "robocal.design.simulate", "Residual": "robocal.residuals",
    "REGISTRY": "robocal.residuals", "RobocalError": "robocal.errors", "InputError": "robocal.errors",
}
__all__ = list(EXPORTS)
__version__ = "0.1.0"


def __getattr__(name):
    if name in EXPORTS:
        value = getattr(import_module(EXPORTS[name]), name)
        globals()[name] = value          # once found, an attribute like any other
        return value
    raise AttributeError(f"module 'robocal' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(EXPORTS))
