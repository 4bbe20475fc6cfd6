"""The scene's camera block: one whole-array undistortion of every detected pixel (robocal.viz.camera_scene.undistorted)
and one batched evaluation of the residual rows give what undistorting and evaluating each term alone gave, so the
scene file's content is unchanged by the speed-up."""
import numpy as np
import pytest

from camera_cases import CAMERA, K_TRUE, camera_scene
from robocal.estimation.camera_block import camera_problem, camera_setup
from robocal.estimation.camera_init import undistort
from robocal.viz.camera_scene import camera_points, undistorted
import robocal.viz.scene as scene_module
from robocal.viz.scene import scene_data


@pytest.fixture(scope="module", params=["eye_in_hand", "eye_to_hand"])
def problem(request):
    robot, _, values, det, target, frame, _ = camera_scene(request.param, n_poses=6, noise=0.3, seed=5)
    setup = camera_setup(robot, robot.joint_names, values, [str(i + 1) for i in range(len(values))], det, target,
                         CAMERA, K_TRUE, mount=request.param, frame=frame, sigma=0.3)
    return camera_problem(robot, robot.joint_names, values, setup, "offsets"), setup.residual


def test_whole_array_undistortion_equals_the_per_pixel_one(problem):
    prob, res = problem
    aux = prob.aux_values(res)
    k = np.asarray(aux[:res.n_intrinsics], float)
    assert np.any(k[4:] != 0)                        # real distortion: the Newton solve has work to do
    xy = undistorted(res, aux)
    one = np.vstack([undistort(res.camera, k, res.measurements[i:i + 1]) for i in range(res.n_terms)])
    # both are Newton solves stopped below a 1e-13 step on |xy| < 1: they agree to rounding
    assert xy.shape == (res.n_terms, 2) and np.max(np.abs(xy - one)) <= 1e-12
    # and they are the undistortion: projected again they land on the detected pixels (to 1e-9 px)
    uv = res.camera.project(np.column_stack([xy, np.ones(len(xy))]), k, False)
    assert np.max(np.abs(uv - res.measurements)) < 1e-9


def test_scene_equals_the_per_point_path(problem, monkeypatch):
    """The whole scene (points, residual rows, camera entry) with the whole-array undistortion and batched rows
    against the same scene with every term undistorted and evaluated alone (the path before the speed-up: no rays
    turns both off), both states, to 1e-12."""
    prob, res = problem
    before = prob.params.copy()
    ident = {"singular_values": [1.0], "rank": 1, "requested": 1, "rtol": 1e-10, "condition": 1.0}
    fast = scene_data(prob, None, before, ident=ident)
    monkeypatch.setattr(scene_module, "undistorted", lambda res, aux: None)     # rays=None: per term
    slow = scene_data(prob, None, before, ident=ident)
    b, ref = fast["blocks"][0], slow["blocks"][0]
    assert b["type"] == "camera" and len(b["measured_after"]) == res.n_terms
    assert b.keys() == ref.keys()
    for key in b:
        if key.startswith(("measured_", "predicted_", "residual_")):
            assert np.max(np.abs(np.array(b[key]) - np.array(ref[key]))) <= 1e-12, key
        else:
            assert b[key] == ref[key], key
