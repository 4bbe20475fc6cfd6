"""Hand-eye calibration side by side with OpenCV, on simulated UR5 data (docs/camera.md, "Against OpenCV").

For each mount (eye-in-hand, eye-to-hand), pixel noise (0.2, 0.3, 0.5 px) and truth (exact joints, or joint zero
offsets of 1-5 mrad of random sign on every joint), over several seeds: 30 poses that keep a 9 x 6 checkerboard
(30 mm squares) in view of a 1280 x 1024 camera with distortion, every corner detected with Gaussian pixel noise.
  OpenCV      calibrateCamera on all images (intrinsics and per-image target poses), then calibrateHandEye's five
              methods on the nominal robot's flange poses (eye-to-hand: the inverted flange poses, as its docs say)
  robocal HE  the hand-eye transform and the target's (or camera's) pose fitted on the pixels, nominal robot,
              intrinsics fixed at calibrateCamera's (what OpenCV's methods get)
  robocal HE+J+K  the hand-eye, the joint zero offsets and the intrinsics jointly (started from calibrateCamera)
Errors: the hand-eye transform against the truth, translation (mm) and rotation (mrad). No camera data can tell
the last joint's zero (eye-in-hand) or the first joint's zero (eye-to-hand) from the hand-eye, so truth and every
estimate are compared with that offset folded into the hand-eye (the camera relative to the flange at the
reading; the camera relative to the first joint at its reading). Reprojection: RMS pixel error of each method's
model over every corner (OpenCV: the nominal robot, its hand-eye and the target pose most consistent with it).

    python3 benchmarks/camera_hand_eye.py [--seeds 5] [--poses 30]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))     # the simulated scenes of the tests

from robocal import CalibrationOptions, calibrate, load_example  # noqa: E402
from camera_cases import CAMERA, K_TRUE, camera_scene  # noqa: E402
from robocal.design.camera_poses import camera_design_problem  # noqa: E402
from robocal.design.selection import DesignMatrix, select_poses  # noqa: E402
from robocal.estimation.camera_init import OPENCV_METHODS, consistency, opencv_hand_eye  # noqa: E402
from robocal.estimation.camera_block import camera_problem, camera_setup, hand_eye_of, separable_hand_eye  # noqa: E402
from robocal.io import opencv_extra  # noqa: E402
from robocal.model.kinematics import ModelState  # noqa: E402
from robocal.model.parameters import ParameterSet  # noqa: E402

def scene(mount, offsets, noise, rng_seed, n_poses, design="random"):
    """The truth robot, readings, detections and the world pose of the fixed object (tests/camera_cases.py). design:
    the first n_poses viewpoints drawn (random), or n_poses of 10 n_poses chosen by D-optimality (what robocal plan
    does: the nominal robot, every corner seen)."""
    if design == "random":
        return camera_scene(mount, n_poses, noise, offsets, rng_seed)
    robot, params, values, det, target, frame, fixed = camera_scene(mount, 10 * n_poses, noise, offsets, rng_seed)
    problem = camera_design_problem(robot, robot.joint_names, values, frame, mount, fixed, target, CAMERA, K_TRUE,
                                    sigma=noise)
    chosen = select_poses(DesignMatrix.from_problem(problem), n_poses, "D").labels
    keep = np.isin(det.samples.astype(int) - 1, chosen)
    relabel = {str(c + 1): str(i + 1) for i, c in enumerate(chosen)}
    det = det.subset(keep)
    det.samples = np.array([relabel[s] for s in det.samples], dtype=object)
    return robot, params, values[chosen], det, target, frame, fixed


def folded(robot, params, values, mount, frame, he_fixed=None):
    return separable_hand_eye(robot, params, robot.joint_names, values[0], mount, frame, "tool0", he_fixed)


def errors(est: pin.SE3, truth: pin.SE3) -> tuple[float, float]:
    d = truth.inverse() * est
    return 1e3 * float(np.linalg.norm(d.translation)), 1e3 * float(np.linalg.norm(pin.log3(d.rotation)))


def opencv_pipeline(det, target, values, mount, images):
    cv2 = opencv_extra.require("calibrateCamera", "calibrateHandEye", what="the benchmark")
    obj = [target.points_of(det.corners[det.samples == s]).astype(np.float32) for s in images]
    img = [det.uv[det.samples == s].astype(np.float32) for s in images]
    _, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, (CAMERA.width, CAMERA.height), None, None)
    k = np.concatenate([[K[0, 0], K[1, 1], K[0, 2], K[1, 2]], dist.ravel()[:5]])
    T = [pin.SE3(cv2.Rodrigues(r)[0], t.ravel()) for r, t in zip(rvecs, tvecs)]
    nominal = ModelState(load_example("ur5"), ParameterSet(), load_example("ur5").joint_names)
    F = [nominal.sample(values[int(s) - 1]).pose("tool0") for s in images]
    F = F if mount == "eye_in_hand" else [f.inverse() for f in F]
    out = {}
    for m in OPENCV_METHODS:
        X = opencv_hand_eye(F, T, m)
        W, _ = consistency(F, T, X)
        # reprojection through the chain F_i X (camera) and W (target), eye-to-hand through X (camera) and F_i^-1 W
        err = []
        for f, s in zip(F, images):
            rows = det.samples == s
            rel = (f * X).inverse() * W if mount == "eye_in_hand" else X.inverse() * f.inverse() * W
            P = target.points_of(det.corners[rows])
            err.append(CAMERA.project(P @ rel.rotation.T + rel.translation, k, False) - det.uv[rows])
        out[m] = (X, float(np.sqrt(np.mean(np.sum(np.vstack(err) ** 2, axis=1)))))
    return k, out


def robocal_fit(det, target, values, mount, frame, k, full):
    robot = load_example("ur5")
    joints = robot.joint_names
    labels = [str(i + 1) for i in range(len(values))]
    setup = camera_setup(robot, joints, values, labels, det, target, CAMERA, k, mount=mount, frame=frame,
                         attached_to="tool0", sigma=0.3, intrinsics_free=full)
    problem = camera_problem(robot, joints, values, setup, "offsets" if full else "none")
    result = calibrate(problem, CalibrationOptions())
    rms = result.after[0].norm_rms["px"]
    he = hand_eye_of(problem, setup)
    return folded(robot, problem.params, values, mount, frame, he), rms, result.status


def trial(mount, offsets, noise, seed, n_poses, design):
    robot, params, values, det, target, frame, fixed = scene(mount, offsets, noise, seed, n_poses, design)
    truth = folded(robot, params, values, mount, frame, fixed)
    images = list(dict.fromkeys(det.samples))
    k, cv = opencv_pipeline(det, target, values, mount, images)
    row = {f"OpenCV {m}": (*errors(X, truth), rms) for m, (X, rms) in cv.items()}
    for label, full in (("robocal HE", False), ("robocal HE+J+K", True)):
        X, rms, status = robocal_fit(det, target, values, mount, frame, k, full)
        row[label] = (*errors(X, truth), rms)
        if status != "converged":
            row[label + " status"] = status
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--poses", type=int, default=30)
    ap.add_argument("--design", choices=("random", "D"), default="random",
                    help="the poses: as drawn, or chosen by D-optimality from ten times as many (robocal plan)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    print(f"# Hand-eye against OpenCV {opencv_extra.opencv().__version__}: UR5, {args.poses} poses ({args.design}), "
          "9 x 6 checkerboard, "
          f"median over {args.seeds} seeds (translation mm / rotation mrad / reprojection px)\n")
    for mount in ("eye_in_hand", "eye_to_hand"):
        for offsets in (False, True):
            for noise in (0.2, 0.3, 0.5):
                rows = [trial(mount, offsets, noise, 1000 * s + int(10 * noise) + 7 * offsets, args.poses, args.design)
                        for s in range(args.seeds)]
                methods = [m for m in rows[0] if not m.endswith("status")]
                med = {m: np.median([r[m] for r in rows], axis=0) for m in methods}
                best_cv = min((m for m in methods if m.startswith("OpenCV")), key=lambda m: med[m][0] + med[m][1])
                bad = [r[m] for r in rows for m in r if m.endswith("status")]
                print(f"## {mount}, {'joint offsets 1-5 mrad' if offsets else 'exact joints'}, {noise} px"
                      + (f" (robocal fits not converged: {bad})" if bad else ""))
                print("| method | translation mm | rotation mrad | reprojection px |\n|---|---|---|---|")
                for m in methods:
                    print(f"| {m}{' (best OpenCV)' if m == best_cv else ''} | {med[m][0]:.3f} | {med[m][1]:.3f} "
                          f"| {med[m][2]:.3f} |")
                full = med["robocal HE+J+K"]
                print(f"best OpenCV / robocal HE+J+K: translation {med[best_cv][0] / full[0]:.1f}x, rotation "
                      f"{med[best_cv][1] / full[1]:.1f}x\n")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
