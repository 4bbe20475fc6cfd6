"""Simulated camera scenes on a UR5 for the camera tests: a 9 x 6 checkerboard, a 1280 x 1024 camera with distortion,
poses that keep the whole target in view (robocal.design.camera_poses), every corner detected with Gaussian noise."""
import numpy as np
import pinocchio as pin

from robocal import load_example
from robocal.design.camera_poses import camera_candidates, look_at, simulate_detections
from robocal.io.camera_target import target_from_dict
from robocal.model.parameters import robot_parameters
from robocal.residuals.camera_model import CameraModel

TARGET = {"type": "checkerboard", "corners": [9, 6], "square": 0.03}
CAMERA = CameraModel("plumb_bob", 1280, 1024)
K_TRUE = np.array([1100.0, 1100.0, 640.0, 512.0, -0.1, 0.05, 0.0005, -0.0003, 0.0])
SEED_READING = np.array([0.0, -1.3, 1.6, -1.9, -1.57, 0.3])
X_TRUE = pin.SE3(pin.rpy.rpyToMatrix(0.02, -0.03, 0.01), np.array([0.04, -0.06, 0.05]))     # camera on tool0
W_TRUE = pin.SE3(pin.rpy.rpyToMatrix(np.pi, 0, 0.3), np.array([0.45, 0.0, 0.0]))             # target in the world
C_TRUE = pin.SE3(look_at(np.array([1.0, 0.0, 0.6]), np.array([0.4, 0.0, 0.3]), 0.0), np.array([1.0, 0.0, 0.6]))
Y_TRUE = pin.SE3(pin.rpy.rpyToMatrix(np.pi, 0, 0.2), np.array([-0.12, -0.075, 0.03]))       # target on tool0


def camera_scene(mount="eye_in_hand", n_poses=20, noise=0.3, offsets=True, seed=0):
    """(truth robot, truth params, readings, detections, target, robot frame, world pose of the fixed object)."""
    rng = np.random.default_rng(seed)
    robot = load_example("ur5")
    joints = robot.joint_names
    target = target_from_dict(TARGET)
    frame, placement, fixed = (("camera", X_TRUE, W_TRUE) if mount == "eye_in_hand" else ("target", Y_TRUE, C_TRUE))
    robot.add_frame(frame, "tool0", placement)
    values = camera_candidates(robot, joints, frame, mount, fixed, target, CAMERA, K_TRUE, n_poses, rng,
                               SEED_READING).values
    params = robot_parameters(robot, joints, "offsets")
    if offsets:
        for j in joints:
            params[f"{j}.offset"].value = rng.uniform(1e-3, 5e-3) * rng.choice([-1, 1])
    det = simulate_detections(robot, params, joints, values, frame, mount, fixed, target, CAMERA, K_TRUE, noise, rng)
    return robot, params, values, det, target, frame, fixed
