"""Dynamics: actuators, friction, external force from motor currents, force-regulated path
following (docs/dynamics.md), a servo simulator, and dynamic identification. See docs/dynamics.md."""
from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.blending import BlendedPath
from robocal.dynamics.current_force_loop import CurrentForceLoop
from robocal.dynamics.differentiation import TickDifferentiator, differentiate
from robocal.dynamics.environment import ConstantForce, Environment, ViscousLoad, Wall
from robocal.dynamics.excitation import FourierTrajectory, fourier_excitation
from robocal.dynamics.external_force import ExternalForceEstimate, ExternalForceEstimator
from robocal.dynamics.force_sensor import ForceSensorSource
from robocal.dynamics.force_filter import ForceFilter
from robocal.dynamics.force_loop import Margins, TangentLoop, admittance_for_margins, margins, tangent_loop
from robocal.dynamics.friction import FrictionModel
from robocal.dynamics.generator import PathGenerator, Setpoint
from robocal.dynamics.identification import (DynamicIdentificationResult, PayloadResult, Segment, identify_dynamics,
                             identify_payload)
from robocal.dynamics.instructions import MotionInstruction, MotionParams, movecf, movejf, movelf
from robocal.dynamics.joint_state import JointState, from_measurements, from_setpoints
from robocal.dynamics.limits import project_limits
from robocal.dynamics.path import CircularPath, JointPath, LinearPath, SplinePath
from robocal.dynamics.payload import payload_inertia, with_payload
from robocal.dynamics.regulator import TangentialForceRegulator
from robocal.dynamics.simulator import RobotSimulator, servo_gains
from robocal.dynamics.stick_slip import StickSlipFriction
from robocal.dynamics.transmission import Transmission
from robocal.dynamics.contact_observer import ContactForceObserver, ObserverSettings
from robocal.dynamics.wrench import WrenchEstimate, WrenchMapper

__all__ = [
    "BlendedPath", "CurrentForceLoop", "ForceFilter", "Margins", "TangentLoop", "admittance_for_margins", "margins", "tangent_loop", "movecf",
    "ActuatorModel", "FrictionModel", "differentiate", "TickDifferentiator", "JointState", "from_measurements",
    "from_setpoints", "ExternalForceEstimator", "ExternalForceEstimate", "WrenchMapper", "WrenchEstimate",
    "ForceSensorSource", "payload_inertia", "with_payload", "LinearPath", "JointPath", "CircularPath",
    "SplinePath", "project_limits", "TangentialForceRegulator", "MotionParams", "MotionInstruction", "movejf",
    "movelf", "PathGenerator", "Setpoint", "RobotSimulator", "servo_gains", "StickSlipFriction", "ContactForceObserver", "ObserverSettings", "Wall",
    "ViscousLoad", "ConstantForce", "Environment", "FourierTrajectory", "fourier_excitation", "Segment",
    "identify_dynamics", "identify_payload", "DynamicIdentificationResult", "PayloadResult", "Transmission",
]
