"""The visual check of a camera block: the scene file's camera entry and points, the meshcat drawing (frustum, target,
rays per image) and the report's per-image figures."""
import json

import numpy as np
import pinocchio as pin
import pytest

from camera_cases import CAMERA, K_TRUE, camera_scene
from robocal import calibrate, load_example
from robocal.estimation.camera_block import camera_problem, camera_setup
from robocal.viz.scene import VERSION, read_scene, scene_bytes

pytest.importorskip("meshcat")


@pytest.fixture(scope="module", params=["eye_in_hand", "eye_to_hand"])
def fitted(request, tmp_path_factory):
    mount = request.param
    _, _, values, det, target, frame, _ = camera_scene(mount, n_poses=6, noise=0.3, seed=3)
    robot = load_example("ur5")
    setup = camera_setup(robot, robot.joint_names, values, [str(i + 1) for i in range(len(values))], det, target,
                         CAMERA, K_TRUE, mount=mount, frame=frame, sigma=0.3)
    problem = camera_problem(robot, robot.joint_names, values, setup, "offsets")
    before = problem.params.copy()
    result = calibrate(problem)
    folder = tmp_path_factory.mktemp(mount)
    (folder / "scene.json").write_bytes(scene_bytes(problem, result, before))
    return mount, problem, setup, read_scene(folder)


def test_scene_holds_the_detections_and_points_on_their_rays(fitted):
    mount, problem, setup, scene = fitted
    assert scene["version"] == VERSION == 3
    b = scene["blocks"][0]
    cam = b["camera"]
    res = setup.residual
    assert cam["mount"] == mount and cam["image_size"] == [1280, 1024] and len(cam["pixels"]) == res.n_terms
    assert np.allclose(cam["intrinsics_after"], problem.aux_values(res)[:9])
    # the measured point lies on the detected pixel's ray: seen from the camera it projects onto the detected pixel
    # (to the undistortion's Newton tolerance); the predicted point is the corner, projecting to detected + residual
    fixed = cam["fixed_after"]
    F = pin.SE3(pin.Quaternion(fixed[6], *fixed[3:6]).toRotationMatrix(), np.array(fixed[:3]))
    frames = scene["frames"]
    for k in range(0, res.n_terms, 7):
        i = b["terms"][k][0]
        p7 = scene["poses"]["after"][i][frames.index(b["frame"])]
        M = pin.SE3(pin.Quaternion(p7[6], *p7[3:6]).toRotationMatrix(), np.array(p7[:3]))
        C = M if mount == "eye_in_hand" else F
        for key, pixel in (("measured_after", np.array(cam["pixels"][k])),
                           ("predicted_after", np.array(cam["pixels"][k]) + np.array(b["residual_after"][k]))):
            X = C.actInv(np.array(b[key][k][0]))
            assert np.allclose(CAMERA.project(X[None], np.array(cam["intrinsics_after"]), False)[0], pixel, atol=1e-6)


def test_meshcat_draws_frustum_target_and_one_image_of_rays_at_a_time(fitted):
    from robocal.viz.meshcat_check import SceneView
    _, _, _, scene = fitted
    view = SceneView(scene, meshes=False).draw(0)
    T, V = view.sample_commands(2)
    rays = {p: v for p, v in V.items() if "/camera/camera/rays/" in p}
    assert len(rays) == 6 and [p for p, v in rays.items() if v] == ["/meshcat/robocal/camera/camera/rays/2"]
    moving = "frustum" if scene["blocks"][0]["camera"]["mount"] == "eye_in_hand" else "target"
    assert np.allclose(T[f"/meshcat/robocal/camera/camera/{moving}"], view.pose("after", 2, scene["blocks"][0]["frame"]))
    page = view.static_html()
    assert f"/meshcat/robocal/camera/camera/{moving}" in page and "frustum (grey lines)" in page   # stepped per sample
    assert "RMS" in view.sample_label(2) and "px (54 corners)" in view.sample_label(2)


def test_report_shows_detected_against_reprojected_per_image(fitted):
    from robocal.viz.report import report_bytes
    _, problem, _, scene = fitted
    page = report_bytes({"parameters": []}, scene, meshes=False).decode()
    assert "Reprojection RMS per image of block &#x27;camera&#x27;" in page
    assert "detected corners (dots) and the calibrated model&#x27;s reprojections (crosses) in the 6 image(s)" in page
    # the camera's pseudo-points stay out of the per-axis histogram of the other blocks' points
    assert "Per-axis error of every drawn point" not in page
    json.dumps(scene)       # still plain data
