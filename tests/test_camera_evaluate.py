"""`robocal evaluate` on a camera config: the calibrated camera and robot scored on another session's images
(examples/camera/: a second session of 10 images, the board moved 2 cm and turned 3 degrees; simulated at 0.3 px
per coordinate), the board's pose re-registered there with --refit."""
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from robocal.cli.main import main

EXAMPLE = Path(__file__).parents[1] / "examples" / "camera"
NOISE_PX = json.loads((EXAMPLE / "truth.json").read_text())["noise_px"]


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    folder = tmp_path_factory.mktemp("camera")
    for name in ("camera.yaml", "joints.csv", "detections.csv", "joints_session2.csv", "detections_session2.csv"):
        shutil.copy(EXAMPLE / name, folder / name)
    assert main(["calibrate", str(folder / "camera.yaml"), "-o", str(folder / "out"), "-q", "--no-report"]) == 0
    return folder


def evaluate(folder, csv, *extra):
    assert main(["evaluate", str(folder / "out"), str(folder / csv), "-q", *extra]) == 0
    stem = Path(csv).stem + ("_refit" if "--refit" in extra else "")
    return json.loads((folder / "out" / f"evaluation_{stem}.json").read_text())


def rms_px(report) -> tuple[int, float]:
    (block,) = report["blocks"]
    assert block["unit"] == "px" and block["norm_of"] == "2D reprojection error"
    return block["all"]["n"], block["all"]["rms_norm"]


def test_the_training_images_score_what_the_fit_left(calibrated):
    """Scored on its own images, the folder's model gives the fit's own residual: the camera frame is placed where
    the fit started it (the training images' closed form), not where the scored images would start it."""
    result = json.loads((calibrated / "out" / "result.json").read_text())
    after = next(b for b in result["residuals_after"] if b["name"] == "camera")
    n, rms = rms_px(evaluate(calibrated, "joints.csv", "--detections", str(calibrated / "detections.csv")))
    assert n == 1080 and rms == pytest.approx(after["rms_norm"]["px"], rel=1e-6)


def test_another_session_with_the_board_re_registered_scores_at_the_noise(calibrated):
    report = evaluate(calibrated, "joints_session2.csv", "--detections", str(calibrated / "detections_session2.csv"),
                      "--refit", "camera.target.*")
    n, rms = rms_px(report)
    # a corner's error norm at 0.3 px per coordinate: RMS sqrt(2) x 0.3 = 0.424 px; over 540 corners its estimate
    # scatters by 2.2 % (chi-square, 2 dof a corner), and the calibrated model's own uncertainty adds a little
    assert n == 540 and np.sqrt(2) * NOISE_PX * 0.93 < rms < np.sqrt(2) * NOISE_PX * 1.12
    assert report["refitted"] == [f"camera.target.{c}" for c in ("x", "y", "z", "rx", "ry", "rz")]
    # every image's every corner, in its sample's entry, and each image's RMS under its label
    assert len(report["per_sample"]) == 10
    assert all(len(s["camera 2D reprojection error (px)"]) == 54 for s in report["per_sample"])
    images = report["blocks"][0]["images"]
    assert sorted(images) == [f"s2img{i:02d}" for i in range(1, 11)] and all(v["n"] == 54 for v in images.values())
    pooled = np.sqrt(np.mean([v["rms_norm"] ** 2 for v in images.values()]))
    assert pooled == pytest.approx(rms, rel=1e-12)


def test_without_re_registering_the_moved_board_the_error_shows_it(calibrated):
    # 2 cm and 3 degrees at ~0.3-0.5 m from a 1100 px focal length: tens of pixels
    _, rms = rms_px(evaluate(calibrated, "joints_session2.csv", "--detections",
                             str(calibrated / "detections_session2.csv")))
    assert rms > 20


def test_a_camera_block_needs_the_new_images_detections(calibrated, capsys):
    out, csv = str(calibrated / "out"), str(calibrated / "joints_session2.csv")
    assert main(["evaluate", out, csv]) == 2
    err = capsys.readouterr().err
    assert "camera block 'camera'" in err and "--detections" in err and "measurements[0].detections" in err
    assert main(["evaluate", out, csv, "--detections", f"eye={calibrated / 'detections_session2.csv'}"]) == 2
    assert "no camera block named eye (camera blocks: camera)" in capsys.readouterr().err
    assert main(["evaluate", out, csv, "--detections", str(calibrated / "missing.csv")]) == 2
    assert "detections file not found" in capsys.readouterr().err


def test_a_camera_frame_the_robot_already_has_is_its_own_start(tmp_path):
    """The camera frame given in the config (as a URDF would have it: roughly placed, 1 cm and 20 mrad off): the
    fit's frame parameters then correct that frame, and the other session is scored from it as it is."""
    for name in ("joints.csv", "detections.csv", "joints_session2.csv", "detections_session2.csv"):
        shutil.copy(EXAMPLE / name, tmp_path / name)
    cfg = yaml.safe_load((EXAMPLE / "camera.yaml").read_text())
    cfg["robot"]["frames"] = [{"name": "camera", "parent": "tool0", "xyz": [0.05, -0.06, 0.05],
                               "rpy": [0.0, -0.03, 0.0]}]
    (tmp_path / "camera.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    assert main(["calibrate", str(tmp_path / "camera.yaml"), "-o", str(tmp_path / "out"), "-q", "--no-report"]) == 0
    result = json.loads((tmp_path / "out" / "result.json").read_text())
    assert abs({p["name"]: p["value"] for p in result["parameters"]}["camera.tx"]) > 5e-3   # it corrected the frame
    _, rms = rms_px(evaluate(tmp_path, "joints_session2.csv", "--detections", str(tmp_path / "detections_session2.csv"),
                             "--refit", "camera.target.*"))
    assert np.sqrt(2) * NOISE_PX * 0.93 < rms < np.sqrt(2) * NOISE_PX * 1.12
