"""The robot model: URDF loading, named parameters, kinematics at a parameter vector, closed chains."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "robot": "Robot load_example load_urdf", "parameters": "Parameter ParameterSet robot_parameters",
    "kinematics": "ModelState SampleState", "loops": "LoopSet assemble",
    "inverse_kinematics": "IKFailure frame_ik reading_ik", "dh_urdf": "DHRow dh_urdf write_dh_urdf"})
