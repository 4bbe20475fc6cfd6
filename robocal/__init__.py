"""robocal: calibrate robot models (serial arms and parallel machines) described by URDF."""
from robocal.errors import InputError, RobocalError
from robocal.model.robot import Robot, load_example, load_urdf

__all__ = ["Robot", "load_urdf", "load_example", "RobocalError", "InputError"]
__version__ = "0.1.0"
