"""The robot model: URDF in and out, MJCF and Pinocchio constraint models in, named parameters, kinematics at a
parameter vector, closed chains, IK."""
from robocal.model.dh_urdf import DHRow, write_dh_urdf
from robocal.model.inverse_kinematics import IKFailure, solve_ik
from robocal.model.joint_relations import Coupling
from robocal.model.kinematics import ModelState, SampleState
from robocal.model.loops import LoopSet, assemble
from robocal.model.mjcf import load_mjcf
from robocal.model.parameters import Parameter, ParameterSet, robot_parameters
from robocal.model.pinocchio_robot import robot_from_pinocchio
from robocal.model.robot import Robot, load_example, load_urdf
from robocal.model.urdf_export import calibrated_urdf, export_urdf

__all__ = ["DHRow", "write_dh_urdf", "IKFailure", "solve_ik", "ModelState", "SampleState", "LoopSet",
           "assemble", "Coupling", "load_mjcf", "robot_from_pinocchio", "Parameter", "ParameterSet", "robot_parameters",
           "Robot", "load_example", "load_urdf", "calibrated_urdf", "export_urdf"]
