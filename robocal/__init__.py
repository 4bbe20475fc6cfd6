"""robocal: calibrate robot models (serial arms and parallel machines) described by URDF, MJCF or Pinocchio.

The names users call; docs/api.md lists them with the subpackages they come from.
"""
from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from robocal.errors import InputError, RobocalError
from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.problem import Problem
from robocal.estimation.result import CalibrationResult
from robocal.workflows.evaluate import evaluate_result
from robocal.workflows.setup import Setup, load_config
from robocal.workflows.outputs import write_results
from robocal.model.urdf_export import export_urdf
from robocal.model.parameters import Parameter, ParameterSet, robot_parameters
from robocal.model.mjcf import load_mjcf
from robocal.model.pinocchio_robot import robot_from_pinocchio
from robocal.model.robot import Robot, load_example, load_urdf
from robocal.residuals import REGISTRY, Residual

__all__ = ["Robot", "load_urdf", "load_example", "load_mjcf", "robot_from_pinocchio", "Parameter", "ParameterSet", "robot_parameters", "Setup",
           "load_config", "Problem", "CalibrationOptions", "calibrate", "CalibrationResult", "evaluate_result",
           "write_results", "export_urdf", "perturb", "random_configurations", "simulate_measurements", "Residual",
           "REGISTRY", "RobocalError", "InputError"]
__version__ = "0.1.0"
