"""Camera observations: the projection, the reprojection residual's Jacobian, the joint fit from detections (synthetic
truth, with robocal's own PnP and hand-eye: OpenCV hidden), and the bad inputs the set-up refuses."""
import numpy as np
import pinocchio as pin
import pytest

from camera_cases import CAMERA, K_TRUE, camera_scene
from robocal import calibrate, load_example
from robocal.errors import InputError
from robocal.estimation.camera_block import camera_problem, camera_setup, hand_eye_of, separable_hand_eye
from robocal.io import opencv_extra
from robocal.io.camera_target import target_from_dict
from robocal.io.detections import read_detections
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.residuals import ReprojectionResidual
from robocal.residuals.camera_model import CameraModel
from robocal.testing import assert_problem_jacobian

DISTORTION = {"plumb_bob": [-0.2, 0.1, 0.001, -0.002, 0.02], "rational": [-0.2, 0.1, 0.001, -0.002, 0.02, 0.01, 0.02, 0.03],
              "fisheye": [0.05, -0.01, 0.003, 0.001]}


@pytest.fixture
def no_opencv(monkeypatch):
    """robocal's own PnP and hand-eye, as on an install without the camera extra."""
    monkeypatch.setattr(opencv_extra, "opencv", lambda: None)


@pytest.mark.parametrize("mount", ["eye_in_hand", "eye_to_hand"])
@pytest.mark.parametrize("model", sorted(DISTORTION))
def test_reprojection_jacobian_matches_finite_differences(model, mount):
    rng = np.random.default_rng(1)
    robot = load_example("ur5")
    robot.add_frame("cam", "tool0", pin.SE3(pin.rpy.rpyToMatrix(0.1, -0.2, 0.3), np.array([0.01, 0.02, 0.1])))
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"cam": True})
    for p in params:          # away from zero, so that exp6's Jacobian matters
        p.value = rng.normal(0, 0.01)
    values = rng.uniform(-2, 2, len(joints)) + rng.normal(0, 0.05, (3, len(joints)))
    samples = np.repeat(np.arange(3), 4)
    points = np.column_stack([rng.uniform(-0.1, 0.1, (len(samples), 2)), np.zeros(len(samples))])
    M = ModelState(robot, params, joints).sample(values[0]).pose("cam")
    near = pin.SE3(pin.exp3(np.array([0.2, 0.1, 0.3])), np.array([0, 0, 1.0]))     # 1 m in front of the camera
    fixed = M * near if mount == "eye_in_hand" else M * near.inverse()
    res = ReprojectionResidual("c", "cam", samples, rng.normal(600, 100, (len(samples), 2)), np.arange(len(samples)),
                               points, CameraModel(model, 1280, 1024), [1000, 1010, 640, 512] + DISTORTION[model],
                               mount=mount, fixed_pose=fixed, term_sigma=rng.uniform(0.2, 1, len(samples)))
    problem = Problem(robot, params, joints, values, [res])
    for p in params:
        if p.kind == "auxiliary":
            p.value += rng.normal(0, 1.0 if p.unit == "px" else 0.01)
    assert res.batched
    assert_problem_jacobian(problem)


@pytest.mark.skipif(not opencv_extra.has("projectPoints", "fisheye.projectPoints"),
                    reason="needs the camera extra (opencv-python-headless)")
@pytest.mark.parametrize("model", sorted(DISTORTION))
def test_projection_matches_opencv(model):
    cv2 = opencv_extra.opencv()
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(-0.3, 0.3, (20, 2)), rng.uniform(0.5, 1.5, 20)])
    cam = CameraModel(model, 1280, 1024)
    k = np.array([1000, 1010, 640, 512] + DISTORTION[model], float)
    if model == "fisheye":
        ref = cv2.fisheye.projectPoints(X[:, None], np.zeros(3), np.zeros(3), cam.camera_matrix(k), k[4:])[0]
    else:
        ref = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cam.camera_matrix(k), k[4:])[0]
    assert np.abs(cam.project(X, k, derivatives=False) - ref.reshape(-1, 2)).max() < 1e-9


@pytest.mark.parametrize("mount", ["eye_in_hand", "eye_to_hand"])
def test_joint_fit_recovers_hand_eye_offsets_and_intrinsics(mount, no_opencv):
    """Joint offsets of 1-5 mrad in the truth, 0.3 px noise, intrinsics started 2 % and 10 px off without distortion."""
    noise = 0.3
    truth_robot, truth, values, det, target, frame, fixed = camera_scene(mount, n_poses=20, noise=noise, seed=5)
    robot = load_example("ur5")
    joints = robot.joint_names
    k0 = K_TRUE * np.array([1.02, 0.98, 1, 1, 0, 0, 0, 0, 0]) + np.array([0, 0, 10, -8, 0, 0, 0, 0, 0])
    setup = camera_setup(robot, joints, values, [str(i + 1) for i in range(len(values))], det, target, CAMERA, k0,
                         mount=mount, frame=frame, sigma=noise)
    assert setup.hand_eye.method == "robocal Park-Martin"
    problem = camera_problem(robot, joints, values, setup, "offsets")
    result = calibrate(problem)
    assert result.status == "converged"
    # the pixel residual matches the simulated noise: sigma^2 ~ chi2(dof)/dof, sd of its root sqrt(1/(2 dof)); 4 sd
    assert abs(np.sqrt(result.sigma2) - 1) < 4 * np.sqrt(1 / (2 * result.dof))
    assert abs(result.after[0].norm_rms["px"] - noise * np.sqrt(2)) < 0.05 * noise
    # every offset the data determine, and the intrinsics, within 4 standard errors of the truth
    for name in [f"{j}.offset" for j in joints] + [f"camera.{n}" for n in CAMERA.names]:
        p = problem.params[name]
        if p.vary and p.prior_sigma is None:
            true = truth[name].value if name in truth else K_TRUE[list(CAMERA.names).index(name.split(".")[1])]
            assert abs(p.value - true) < 4 * p.stderr, (name, p.value, true, p.stderr)
    # the hand-eye as camera data determine it: translation to 4 sd (about 0.05 mm a component at 20 poses), the
    # rotation as well as the principal point (0.6 px / 1100 px ~ 0.5 mrad a component, 4 sd)
    he = hand_eye_of(problem, setup)
    est = separable_hand_eye(robot, problem.params, joints, values[0], mount, frame, "tool0", he)
    true = separable_hand_eye(truth_robot, truth, joints, values[0], mount, frame, "tool0", fixed)
    d = true.inverse() * est
    assert np.linalg.norm(d.translation) < 0.5e-3 and np.linalg.norm(pin.log3(d.rotation)) < 2e-3
    # the camera (target) frame is registered before the joints: the last joint's zero, which no image tells
    # from the frame's turn about that axis, stays at its nominal zero and the frame's placement takes it, so the
    # fitted frame already is the separable hand-eye (eye-in-hand) and the statements name the joint
    assert problem.params["wrist_3_joint.offset"].value == pytest.approx(0.0, abs=1e-9)
    if mount == "eye_in_hand":
        d_direct = est.inverse() * he
        assert np.linalg.norm(d_direct.translation) < 1e-9 and np.linalg.norm(pin.log3(d_direct.rotation)) < 1e-9
    assert any("Set by the prior only" in s and "wrist_3_joint.offset" in s for s in result.summary().splitlines())


# ---- bad input ----------------------------------------------------------------------------------------------------
def _setup(det, target=None, camera=CAMERA, k=K_TRUE, n=None):
    robot, _, values, _, tgt, frame, _ = _SCENE
    labels = [str(i + 1) for i in range(len(values))]
    return camera_setup(load_example("ur5"), robot.joint_names, values, labels, det, target or tgt, camera, k,
                        frame=frame)


_SCENE = camera_scene("eye_in_hand", n_poses=6, noise=0.3, seed=2)


def _csv(tmp_path, det, mutate):
    rows = ["sample,corner,u,v"] + [f"{s},{c},{u:.4f},{v:.4f}" for s, c, (u, v) in zip(det.samples, det.corners, det.uv)]
    mutate(rows)
    path = tmp_path / "detections.csv"
    path.write_text("\n".join(rows) + "\n")
    return read_detections(path)


def test_corner_id_not_on_the_target_names_its_line(tmp_path):
    det = _csv(tmp_path, _SCENE[3], lambda rows: rows.__setitem__(5, "1,99,600.0,500.0"))   # line 6
    with pytest.raises(InputError, match="corner id 99 is not on the checkerboard") as err:
        _setup(det)
    assert err.value.row == 6 and err.value.field == "corner" and err.value.source.endswith("detections.csv")


def test_sample_with_too_few_corners_is_named(tmp_path):
    det = _csv(tmp_path, _SCENE[3], lambda rows: [rows.pop(k) for k in range(len(rows) - 1, 0, -1)
                                                  if rows[k].startswith("2,") and int(rows[k].split(",")[1]) > 3])
    with pytest.raises(InputError, match="sample 2 has 4 corners; at least 6"):
        _setup(det)


def test_pixel_outside_the_image_is_refused(tmp_path):
    det = _csv(tmp_path, _SCENE[3], lambda rows: rows.__setitem__(3, "1,2,1500.5,300.0"))   # line 4
    with pytest.raises(InputError, match="outside the 1280 x 1024 image") as err:
        _setup(det)
    assert err.value.row == 4 and err.value.field == "u"


def test_intrinsics_in_mm_are_refused():
    with pytest.raises(InputError, match="fx = 8 is not a focal length in pixels"):
        _setup(_SCENE[3], k=np.array([8.0, 8.0, 640, 512, 0, 0, 0, 0, 0]))


def test_target_seen_from_behind_is_refused(no_opencv):
    # the corner numbering of a board seen from its back: mirrored along x
    mirrored = target_from_dict({"type": "points", "points": {
        int(i): [0.24 - x, y, 0.0] for i, (x, y, _) in zip(_SCENE[4].ids, _SCENE[4].points)}})
    with pytest.raises(InputError, match="seen from behind in 6 image"):
        _setup(_SCENE[3], target=mirrored)


def test_detections_file_errors_name_line_and_column(tmp_path):
    path = tmp_path / "d.csv"
    path.write_text("sample,corner,u\n1,0,3\n")
    with pytest.raises(InputError, match="missing: v"):
        read_detections(path)
    path.write_text("sample,corner,u,v\n1,0,3,4\n1,0,5,6\n")
    with pytest.raises(InputError, match="corner 0 twice") as err:
        read_detections(path)
    assert err.value.row == 3


def test_bad_target_geometry_names_the_key():
    with pytest.raises(InputError, match="two integers") as err:
        target_from_dict({"type": "checkerboard", "corners": [9], "square": 0.03})
    assert err.value.field == "target.corners"
    with pytest.raises(InputError, match="smaller than the square"):
        target_from_dict({"type": "charuco", "squares": [5, 4], "square": 0.03, "marker": 0.04})
