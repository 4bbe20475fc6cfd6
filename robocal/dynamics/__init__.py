"""Dynamics: actuators, friction, external force from motor currents, force-regulated path
following (seed 004), a servo simulator, and dynamic identification. See docs/dynamics.md."""
from .actuators import ActuatorModel
from .differentiation import TickDifferentiator, differentiate
from .environment import ConstantForce, Environment, ViscousLoad, Wall
from .excitation import FourierTrajectory, fourier_excitation
from .external_force import ExternalForceEstimate, ExternalForceEstimator
from .force_sensor import ForceSensorSource
from .friction import FrictionModel
from .generator import PathGenerator, Setpoint
from .identification import (DynamicIdentificationResult, PayloadResult, Segment, identify_dynamics,
                             identify_payload)
from .instructions import MotionInstruction, MotionParams, movejf, movelf
from .inverse_kinematics import IKFailure, solve_ik
from .joint_state import JointState, from_measurements, from_setpoints
from .limits import project_limits
from .path import CircularPath, JointPath, LinearPath, SplinePath
from .payload import payload_inertia, with_payload
from .regulator import TangentialForceRegulator
from .simulator import RobotSimulator, servo_gains
from .wrench import WrenchEstimate, WrenchMapper

__all__ = [
    "ActuatorModel", "FrictionModel", "differentiate", "TickDifferentiator", "JointState", "from_measurements",
    "from_setpoints", "ExternalForceEstimator", "ExternalForceEstimate", "WrenchMapper", "WrenchEstimate",
    "ForceSensorSource", "payload_inertia", "with_payload", "LinearPath", "JointPath", "CircularPath",
    "SplinePath", "project_limits", "TangentialForceRegulator", "MotionParams", "MotionInstruction", "movejf",
    "movelf", "PathGenerator", "Setpoint", "solve_ik", "IKFailure", "RobotSimulator", "servo_gains", "Wall",
    "ViscousLoad", "ConstantForce", "Environment", "FourierTrajectory", "fourier_excitation", "Segment",
    "identify_dynamics", "identify_payload", "DynamicIdentificationResult", "PayloadResult",
]
