"""A camera block in the calibration YAML: `robocal calibrate / cv` on examples/camera/ (simulated detections shipped
in the repo; the truth in truth.json), `robocal plan`'s viewpoints, the commands that refuse a camera block, and the
block's key checks."""
import json
import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from robocal import load_example
from robocal.cli.main import main
from robocal.errors import InputError
from robocal.estimation.camera_block import separable_hand_eye
from robocal.io.camera_target import target_from_dict
from robocal.model.kinematics import ModelState
from robocal.model.parameters import ParameterSet, robot_parameters
from robocal.residuals.camera_model import camera_spec_from_dict
from robocal.workflows.config_read import parse_config
from robocal.workflows.plan import plan_from_config, write_plan
from robocal.workflows.select import select_model

EXAMPLE = Path(__file__).parents[1] / "examples" / "camera"


@pytest.fixture
def example(tmp_path):
    for name in ("camera.yaml", "joints.csv", "detections.csv"):
        shutil.copy(EXAMPLE / name, tmp_path / name)
    return tmp_path / "camera.yaml"


def _truth_hand_eye(truth, values):
    """The camera on tool0 as camera data tell it (the last joint's true zero folded in), from truth.json."""
    robot = load_example("ur5")
    he = truth["camera_on_tool0"]
    robot.add_frame("camera", "tool0", pin.SE3(pin.rpy.rpyToMatrix(*he["rpy"]), np.array(he["xyz"])))
    params = robot_parameters(robot, robot.joint_names, "offsets")
    params.set_values({f"{j}.offset": v for j, v in truth["joint_offsets_rad"].items()})
    return separable_hand_eye(robot, params, robot.joint_names, values[0], "eye_in_hand", "camera")


def test_calibrate_from_the_config_alone(example, tmp_path):
    out = tmp_path / "out"
    assert main(["calibrate", str(example), "-o", str(out), "-q", "--no-report"]) == 0
    result = json.loads((out / "result.json").read_text())
    cams = json.loads((out / "hand_eye.json").read_text())
    truth = json.loads((EXAMPLE / "truth.json").read_text())
    assert result["status"] == "converged"
    # the pixel residual matches the simulated noise: sigma^2 ~ chi2(dof)/dof, sd of its root sqrt(1/(2 dof)); 4 sd
    assert abs(result["sigma_ratio"] - 1) < 4 * np.sqrt(1 / (2 * result["degrees_of_freedom"]))
    # the joint zeros the images determine (not the first, which the board's pose takes, nor the last, which the
    # camera frame takes), within 4 standard errors of the truth
    params = {p["name"]: p for p in result["parameters"]}
    for j in ("shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint"):
        p = params[f"{j}.offset"]
        assert abs(p["value"] - truth["joint_offsets_rad"][j]) < 4 * p["stderr"], (j, p)
    for name, true in truth["intrinsics"].items():
        k = cams["camera"]["intrinsics"][name]
        assert abs(k["value"] - true) < 4 * k["stderr"], (name, k, true)
    # the hand-eye as the images tell it: translation within 0.5 mm, rotation within 2 mrad (20 images at 0.3 px:
    # the principal point's ~0.8 px standard error is ~0.7 mrad of camera rotation; tests/test_camera.py)
    values = np.loadtxt(EXAMPLE / "joints.csv", delimiter=",", skiprows=1, usecols=range(1, 7))
    frame = cams["camera"]["frame"]
    est = pin.SE3(pin.rpy.rpyToMatrix(*frame["rpy"]), np.array(frame["xyz"]))
    d = _truth_hand_eye(truth, values).inverse() * est
    assert np.linalg.norm(d.translation) < 0.5e-3 and np.linalg.norm(pin.log3(d.rotation)) < 2e-3
    assert frame["relative_to"] == "tool0" and len(cams["camera"]["images"]) == 20
    written = yaml.safe_load((out / "config.yaml").read_text())["measurements"][0]
    assert Path(written["detections"]).is_absolute() and written["mount"] == "eye_in_hand"


def test_cv_holds_out_images_and_scores_pixels(example, capsys):
    assert main(["cv", str(example), "--folds", "3"]) == 0
    out = capsys.readouterr().out
    # the held-out pixel error of a model that explains the images: near the simulated 0.3 px per coordinate,
    # sqrt(2) x 0.3 = 0.42 px per corner; 0.6 px would mean a model that does not carry over to other images
    held_out = float(out.split("held-out RMS ")[-1].split(" px")[0])
    assert "(px)" in out and 0.35 < held_out < 0.6


def test_simulate_cannot_take_a_camera_block_and_says_so(example, tmp_path, capsys):
    # (robocal evaluate takes one with the new images' detections: tests/test_camera_evaluate.py)
    assert main(["simulate", str(example), "-o", str(tmp_path / "sim.csv")]) == 2
    err = capsys.readouterr().err
    assert "robocal simulate does not take camera blocks" in err and "measurements[0].type" in err
    assert not (tmp_path / "sim.csv").exists()


def test_an_image_s_corners_are_not_repeated_postures_but_an_image_taken_twice_is(example):
    """Every corner of an image shares its posture: the posture check tells corners apart by their id, so the
    example has no repeats, and an image recorded again at the same joint readings repeats all its corners."""
    from robocal.workflows.evaluate import setup_for_data
    from robocal.workflows.posture_check import posture_counts
    (count,) = posture_counts(setup_for_data(example))
    assert count.repeated_rows == [] and count.copied_rows == [] and count.distinct_rows == 2 * 1080
    joints = (example.parent / "joints.csv").read_text().splitlines()
    again = "again," + joints[3].split(",", 1)[1]              # img03's readings under a new label
    (example.parent / "joints.csv").write_text("\n".join(joints + [again]) + "\n")
    det = (example.parent / "detections.csv").read_text().splitlines()
    shifted = [line.replace("img03,", "again,", 1) for line in det if line.startswith("img03,")]
    (example.parent / "detections.csv").write_text("\n".join(det + shifted) + "\n")
    (count,) = posture_counts(setup_for_data(example))
    # the same readings and the same pixels: each of the image's corners is a copy, counted once
    assert len(count.copied_rows) == len(shifted) == 54 and count.distinct_rows == 2 * 1080


def _block(**change):
    block = yaml.safe_load((EXAMPLE / "camera.yaml").read_text())["measurements"][0]
    block.update(change)
    return {"robot": {"example": "ur5"}, "data": {"csv": "joints.csv"}, "measurements": [block]}


@pytest.mark.parametrize("change, field, message", [
    ({"attach_to": "tool0"}, "measurements[0].attach_to", "did you mean 'attached_to'"),
    ({"mount": "on_hand"}, "measurements[0].mount", "eye_in_hand, eye_to_hand"),
    ({"camera": {"image_size": [1280, 1024], "intrinsics": [1000, 1000, 640]}}, "measurements[0].camera.intrinsics",
     "has 9 intrinsics"),
    ({"camera": {"image_size": [1280, 1024], "intrinsics": {"fx": 1e3, "fy": 1e3, "cx": 640, "cy": 512},
                 "prior": {"fz": 1.0}}}, "measurements[0].camera.prior.fz", "no intrinsic named 'fz'"),
    ({"camera": {"image_size": [1280, 1024], "intrinsics": {"fx": 1e3, "fy": 1e3, "cx": 640, "cy": 512},
                 "focal": 3}}, "measurements[0].camera.focal", "unknown key"),
    ({"target": {"type": "checkerboard", "corners": [9, 6], "sqare": 0.03}}, "measurements[0].target.sqare",
     "unknown key"),
    ({"sigma": -0.3}, "measurements[0].sigma", "positive"),
])
def test_block_keys_are_checked_with_their_path(change, field, message):
    with pytest.raises(InputError, match=message) as err:
        parse_config(_block(**change), EXAMPLE, "camera.yaml")
    assert err.value.field == field


def test_plan_keeps_the_target_in_view_and_beats_random_poses(example, tmp_path):
    cfg = yaml.safe_load(example.read_text())
    cfg["plan"] = {"N": 12, "candidates": {"count": 80}, "validation": 30, "curve": [12], "seed": 3}
    example.write_text(yaml.safe_dump(cfg))
    plan = plan_from_config(example)
    write_plan(plan, tmp_path / "plan")
    assert plan.selection.identifiability.ok and len(plan.poses) == 12
    poses = np.loadtxt(tmp_path / "plan" / "poses.csv", delimiter=",", skiprows=1)[:, 1:]
    assert np.allclose(poses, plan.poses)
    # every chosen pose shows every corner inside the image on the nominal robot (camera frame at tool0, the board
    # where world_pose says)
    robot = load_example("ur5")
    world = cfg["measurements"][0]["world_pose"]
    board = pin.SE3(pin.rpy.rpyToMatrix(*world["rpy"]), np.array(world["xyz"]))
    target = target_from_dict(cfg["measurements"][0]["target"])
    spec = camera_spec_from_dict(cfg["measurements"][0]["camera"])
    ms = ModelState(robot, ParameterSet(), robot.joint_names)
    for q in poses:
        rel = ms.sample(q).pose("tool0").inverse() * board
        X = target.points @ rel.rotation.T + rel.translation
        assert np.all(X[:, 2] > 0) and np.all(spec.model.inside(spec.model.project(X, spec.intrinsics, False)))
    # D-optimal: a larger information determinant than every one of 20 random sets of as many candidates (the
    # exchange ends where no single swap helps, so it cannot lose to a random set by more than rounding)
    rng = np.random.default_rng(4)
    chosen = plan.design.information(plan.selection.chosen)
    logdet = np.linalg.slogdet(chosen)[1]
    random_sets = [np.linalg.slogdet(plan.design.information(rng.choice(plan.design.n_candidates, 12, replace=False)))[1]
                   for _ in range(20)]
    assert logdet > max(random_sets)


def test_select_chooses_joint_offsets_for_a_truth_of_joint_offsets(example):
    """The truth's only robot errors are joint zeros: the ladder's registration rung cannot explain the images and
    the full geometric rung gains nothing on held-out images, so the one-standard-error rule picks joint offsets."""
    selection = select_model(example, folds=2)
    assert selection.rungs[selection.chosen].name == "joint offsets"
    assert selection.rungs[selection.chosen].cv.unit == "px"
    registration = selection.rungs[0].cv
    assert registration.rms > 3 * selection.rungs[selection.chosen].cv.rms
