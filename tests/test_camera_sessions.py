"""A camera block over two sessions (data.sessions) with the board placed anew between them: examples/camera/'s
two simulated sessions (the board moved 2 cm and turned 3 degrees, truth.json) fitted jointly, the second session's
placement a frame of its own; and leave-one-session-out on them."""
import json
import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from robocal.cli.main import main

EXAMPLE = Path(__file__).parents[1] / "examples" / "camera"
TRUTH = json.loads((EXAMPLE / "truth.json").read_text())
NOISE = 0.3       # px per coordinate, the simulations' (and the example's) detection noise


def two_sessions(folder: Path, labelled: bool = True) -> Path:
    """examples/camera/camera_sessions.yaml and its files in `folder`; labelled=False drops the joints files'
    sample column, so the images of both sessions are named by row number (1, 2, ...)."""
    for name in ("camera_sessions.yaml", "joints.csv", "joints_session2.csv", "detections.csv",
                 "detections_session2.csv"):
        shutil.copy(EXAMPLE / name, folder / name)
    if not labelled:
        for name in ("joints.csv", "joints_session2.csv"):
            lines = (folder / name).read_text().splitlines()
            (folder / name).write_text("\n".join([lines[0].replace("sample,", "label,")] + lines[1:]) + "\n")
    return folder / "camera_sessions.yaml"


def test_two_board_placements_fit_jointly_and_the_move_is_recovered(tmp_path):
    out = tmp_path / "out"
    assert main(["calibrate", str(two_sessions(tmp_path)), "-o", str(out), "-q", "--no-report"]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["status"] == "converged"
    first, moved = result["sessions"]
    # each session at the simulated noise: a corner's norm sqrt(2) x 0.3 = 0.424 px, its RMS over 1080 / 540
    # corners within 3 of its 3.0 % / 4.3 % relative scatter (chi-square, 2 dof a corner; half that for the RMS)
    for s, n in ((first, 1080), (moved, 540)):
        rms = s["rms_norm_after"]["camera (px)"]
        assert abs(rms / (np.sqrt(2) * TRUTH["noise_px"]) - 1) < 3 / np.sqrt(2 * n), (s["session"], rms)
    # the second session's frame is the board's move, seen from the robot: W1 W2^-1 (within 4 standard errors)
    w1, w2 = (pin.SE3(pin.rpy.rpyToMatrix(*TRUTH[k]["rpy"]), np.array(TRUTH[k]["xyz"]))
              for k in ("target_in_world", "target_in_world_session2"))
    move = w1 * w2.inverse()
    fc = moved["frame_correction"]
    assert abs(fc["translation_mm"] - 1e3 * np.linalg.norm(move.translation)) < 4 * np.linalg.norm(fc["stderr_mm"])
    assert abs(fc["rotation_mrad"] - 1e3 * np.linalg.norm(pin.log3(move.rotation))) < 4 * np.linalg.norm(
        fc["stderr_mrad"])
    fixed = json.loads((out / "hand_eye.json").read_text())["camera"]["fixed"]
    assert fixed["what"].startswith("target in the world (session 'first'")
    # the joint zeros the images determine, within 4 standard errors of the truth (as with one session)
    params = {p["name"]: p for p in result["parameters"]}
    for j in ("shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint"):
        p = params[f"{j}.offset"]
        assert abs(p["value"] - TRUTH["joint_offsets_rad"][j]) < 4 * p["stderr"], (j, p)


def test_leave_one_session_out_refits_the_held_out_board(tmp_path, capsys):
    assert main(["cv", str(two_sessions(tmp_path))]) == 0
    out = capsys.readouterr().out
    held_out = float(out.split("held-out RMS ")[-1].split(" px")[0])
    # each session predicted by the other's fit, its board re-registered: near the noise (0.424 px), with 10 or
    # 20 images' worth of calibration error on top
    assert "leave-one-session-out" in out and 0.38 < held_out < 0.6


def test_images_named_alike_in_two_sessions_are_refused(tmp_path, capsys):
    assert main(["calibrate", str(two_sessions(tmp_path, labelled=False)), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "is in two sessions" in err and "measurements[0].detections" in err
    assert not (tmp_path / "out").exists()


def test_a_session_column_and_one_detections_file_are_the_same_two_sessions(tmp_path):
    """One joints CSV with a session column and one detections file give the fit of the shipped config (a joints
    file and a detections file a session)."""
    listed, column = tmp_path / "listed", tmp_path / "column"
    listed.mkdir(), column.mkdir()
    config = two_sessions(listed)
    rows = [f"{line},{name}" for name, csv in (("first", "joints.csv"), ("moved", "joints_session2.csv"))
            for line in (listed / csv).read_text().splitlines()[1:]]
    header = (listed / "joints.csv").read_text().splitlines()[0] + ",session"
    (column / "joints.csv").write_text("\n".join([header] + rows) + "\n")
    second = (listed / "detections_session2.csv").read_text().splitlines()[1:]
    (column / "detections.csv").write_text((listed / "detections.csv").read_text() + "\n".join(second) + "\n")
    cfg = yaml.safe_load(config.read_text())
    cfg["data"] = {"csv": "joints.csv", "session_column": "session"}
    cfg["measurements"][0]["detections"] = "detections.csv"
    (column / "one.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    values = []
    for path in (config, column / "one.yaml"):
        assert main(["calibrate", str(path), "-o", str(path.parent / "out"), "-q", "--no-report"]) == 0
        result = json.loads((path.parent / "out" / "result.json").read_text())
        values.append({p["name"]: p["value"] for p in result["parameters"]})
    assert values[0].keys() == values[1].keys() and any(n.startswith("base@moved.") for n in values[0])
    assert all(abs(values[0][n] - values[1][n]) < 1e-9 for n in values[0])


def test_a_label_in_two_detections_files_and_a_missing_file_name_their_place(tmp_path, capsys):
    config = two_sessions(tmp_path)
    lines = (tmp_path / "detections_session2.csv").read_text().splitlines()
    lines[5] = lines[5].replace("s2img01,", "img01,", 1)       # the first session's image, in the second file
    (tmp_path / "detections_session2.csv").write_text("\n".join(lines) + "\n")
    assert main(["calibrate", str(config), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "detections_session2.csv, row 6" in err and "sample img01 is also in" in err and "detections.csv" in err
    cfg = yaml.safe_load(config.read_text())
    cfg["measurements"][0]["detections"] = ["detections.csv", "elsewhere.csv"]
    config.write_text(yaml.safe_dump(cfg))
    assert main(["calibrate", str(config), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "detections file not found" in err and "measurements[0].detections[1]" in err
    assert not (tmp_path / "out").exists()


def test_eye_to_hand_the_camera_moved_between_sessions(tmp_path):
    """Eye-to-hand: a camera fixed in the world, moved 3 cm and turned 2 degrees between two sessions of 12 images
    (simulated, 0.3 px); the target rides on tool0. The second session's frame is the camera's move seen from the
    robot, C1 C2^-1, within 4 standard errors, and both sessions fit at the noise."""
    from camera_cases import C_TRUE, CAMERA, K_TRUE, SEED_READING, TARGET, Y_TRUE
    from robocal import load_example
    from robocal.design.camera_poses import camera_candidates, simulate_detections
    from robocal.io.camera_target import target_from_dict
    from robocal.io.detections import write_detections
    from robocal.io.tables import write_csv
    from robocal.model.parameters import robot_parameters

    rng = np.random.default_rng(4)
    robot = load_example("ur5")
    joints = robot.joint_names
    target = target_from_dict(TARGET)
    robot.add_frame("target", "tool0", Y_TRUE)
    truth = robot_parameters(robot, joints, "offsets")
    moved = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, np.radians(2.0)), np.array([0.02, -0.02, 0.01])) * C_TRUE
    sessions = []
    for s, (name, camera_pose) in enumerate((("first", C_TRUE), ("moved", moved))):
        values = camera_candidates(robot, joints, "target", "eye_to_hand", camera_pose, target, CAMERA, K_TRUE, 12,
                                   rng, SEED_READING).values
        labels = 100 * (s + 1) + np.arange(1, len(values) + 1)        # 101..., 201...: distinct across sessions
        det = simulate_detections(robot, truth, joints, values, "target", "eye_to_hand", camera_pose, target, CAMERA,
                                  K_TRUE, NOISE, rng, [str(lab) for lab in labels])
        write_csv(tmp_path / f"joints_{name}.csv", {"sample": labels, **dict(zip(joints, values.T))})
        write_detections(tmp_path / f"detections_{name}.csv", det)
        sessions.append({"name": name, "csv": f"joints_{name}.csv"})
    block = {"type": "camera", "name": "cam", "frame": "target", "attached_to": "tool0", "mount": "eye_to_hand",
             "detections": ["detections_first.csv", "detections_moved.csv"], "target": TARGET,
             "camera": {"model": "plumb_bob", "image_size": [1280, 1024], "intrinsics": K_TRUE.tolist(), "free": False},
             "sigma": NOISE}
    config = tmp_path / "cam.yaml"
    config.write_text(yaml.safe_dump({"robot": {"example": "ur5"}, "data": {"sessions": sessions},
                                      "parameters": {"preset": "offsets"}, "measurements": [block]}))
    assert main(["calibrate", str(config), "-o", str(tmp_path / "out"), "-q", "--no-report"]) == 0
    result = json.loads((tmp_path / "out" / "result.json").read_text())
    assert result["status"] == "converged"
    first, second = result["sessions"]
    for s in (first, second):          # 12 images x 54 corners: the RMS within 3 of its 2.8 % scatter
        assert abs(s["rms_norm_after"]["cam (px)"] / (np.sqrt(2) * NOISE) - 1) < 3 / np.sqrt(2 * 12 * 54)
    move = C_TRUE * moved.inverse()
    fc = second["frame_correction"]
    assert abs(fc["translation_mm"] - 1e3 * np.linalg.norm(move.translation)) < 4 * np.linalg.norm(fc["stderr_mm"])
    assert abs(fc["rotation_mrad"] - 1e3 * np.linalg.norm(pin.log3(move.rotation))) < 4 * np.linalg.norm(
        fc["stderr_mrad"])
