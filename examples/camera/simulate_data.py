"""Writes the simulated data of examples/camera/ (joints.csv, detections.csv, truth.json); the shipped files are its
output, so `robocal calibrate examples/camera/camera.yaml` runs without this script.

The truth: a UR5 whose six joint zeros are off by 1-5 mrad (random signs), an eye-in-hand camera 1280 x 1024 with
distortion on tool0, a 9 x 6 checkerboard of 30 mm squares fixed in front of the robot. 20 poses that keep the
whole board in view (robocal.design.camera_candidates), every corner detected with 0.3 px Gaussian noise.
A second session of 10 images (joints_session2.csv, detections_session2.csv) on the same robot and camera, the
board moved 2 cm and turned 3 degrees: what `robocal evaluate ... --detections` scores (docs/camera.md).

Run: OMP_NUM_THREADS=1 python examples/camera/simulate_data.py
"""
import json
from pathlib import Path

import numpy as np
import pinocchio as pin

from robocal import load_example
from robocal.design import camera_candidates, simulate_detections
from robocal.io import target_from_dict, write_detections
from robocal.model import robot_parameters
from robocal.residuals import CameraModel

HERE = Path(__file__).parent
CAMERA = CameraModel("plumb_bob", 1280, 1024)
K_TRUE = np.array([1100.0, 1100.0, 640.0, 512.0, -0.1, 0.05, 0.0005, -0.0003, 0.0])
TARGET = {"type": "checkerboard", "corners": [9, 6], "square": 0.03}
CAMERA_ON_TOOL0 = pin.SE3(pin.rpy.rpyToMatrix(0.02, -0.03, 0.01), np.array([0.04, -0.06, 0.05]))
TARGET_IN_WORLD = pin.SE3(pin.rpy.rpyToMatrix(np.pi, 0, 0.3), np.array([0.45, 0.0, 0.0]))
SEED_READING = np.array([0.0, -1.3, 1.6, -1.9, -1.57, 0.3])
N_POSES, NOISE_PX = 20, 0.3
TARGET_SESSION2 = pin.SE3(pin.rpy.rpyToMatrix(np.pi, 0, 0.3 + np.radians(3.0)), np.array([0.47, -0.01, 0.0]))
N_POSES_SESSION2 = 10


def main():
    rng = np.random.default_rng(36)
    robot = load_example("ur5")
    joints = robot.joint_names
    target = target_from_dict(TARGET)
    robot.add_frame("camera", "tool0", CAMERA_ON_TOOL0)
    values = camera_candidates(robot, joints, "camera", "eye_in_hand", TARGET_IN_WORLD, target, CAMERA, K_TRUE,
                               N_POSES, rng, SEED_READING).values
    truth = robot_parameters(robot, joints, "offsets")
    for j in joints:
        truth[f"{j}.offset"].value = rng.uniform(1e-3, 5e-3) * rng.choice([-1, 1])
    det = write_images(robot, truth, joints, target, TARGET_IN_WORLD, values, "img", rng, "")
    doc = {"joint_offsets_rad": {j: truth[f"{j}.offset"].value for j in joints},
           "camera_on_tool0": {"xyz": CAMERA_ON_TOOL0.translation.tolist(),
                               "rpy": pin.rpy.matrixToRpy(CAMERA_ON_TOOL0.rotation).tolist()},
           "target_in_world": {"xyz": TARGET_IN_WORLD.translation.tolist(),
                               "rpy": pin.rpy.matrixToRpy(TARGET_IN_WORLD.rotation).tolist()},
           "intrinsics": dict(zip(CAMERA.names, K_TRUE.tolist())), "noise_px": NOISE_PX}
    doc["target_in_world_session2"] = {"xyz": TARGET_SESSION2.translation.tolist(),
                                       "rpy": pin.rpy.matrixToRpy(TARGET_SESSION2.rotation).tolist()}
    (HERE / "truth.json").write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {len(values)} images, {len(det.corners)} corners to {HERE}")
    second_session(robot, truth, joints, target)


def second_session(robot, truth, joints, target):
    """The same robot and camera, the board moved: new viewpoints, new noise (its own random stream)."""
    rng = np.random.default_rng(37)
    values = camera_candidates(robot, joints, "camera", "eye_in_hand", TARGET_SESSION2, target, CAMERA, K_TRUE,
                               N_POSES_SESSION2, rng, SEED_READING).values
    det = write_images(robot, truth, joints, target, TARGET_SESSION2, values, "s2img", rng, "_session2")
    print(f"wrote the second session: {len(values)} images, {len(det.corners)} corners")


def write_images(robot, truth, joints, target, target_pose, values, label, rng, suffix):
    """Simulate every image's corners seen from `values` and write joints{suffix}.csv and detections{suffix}.csv."""
    labels = [f"{label}{i + 1:02d}" for i in range(len(values))]
    det = simulate_detections(robot, truth, joints, values, "camera", "eye_in_hand", target_pose, target, CAMERA,
                              K_TRUE, NOISE_PX, rng, labels)
    rows = [",".join(["sample", *joints])] + [",".join([lab, *(f"{v:.17g}" for v in row)])
                                                for lab, row in zip(labels, values)]
    (HERE / f"joints{suffix}.csv").write_text("\n".join(rows) + "\n")
    write_detections(HERE / f"detections{suffix}.csv", det)
    return det


if __name__ == "__main__":
    main()
