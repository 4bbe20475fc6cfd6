"""The robot model: URDF loading, named parameters, kinematics at a parameter vector, closed chains."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "loops": "assemble LoopSet", "dh_urdf": "DHRow write_dh_urdf",
    "inverse_kinematics": "frame_ik IKFailure reading_ik", "robot": "load_example load_urdf Robot",
    "kinematics": "ModelState SampleState", "parameters": "Parameter ParameterSet robot_parameters"})
