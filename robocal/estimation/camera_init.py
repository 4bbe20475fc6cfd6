"""Starting values of a camera calibration without a good guess: per-image PnP and a closed-form hand-eye.

PnP: the target's pose in the camera from one image's corners. OpenCV's solvePnP where the extra is installed
(pinhole, plumb_bob, rational: its own distortion models), else robocal's: undistort (Newton on the projection),
a homography (planar target) or a DLT (3D target), then Levenberg-Marquardt on the pixels; either way the pose is
polished on the pixels with robocal's projection, so both paths end at the same optimum.
Hand-eye: both mounts are F_i X T_i = W for all images i (docs/camera.md): eye-in-hand F_i the flange in the world,
X the camera on the flange, T_i the target in the camera, W the target in the world; eye-to-hand F_i the world in
the flange, X the camera in the world, W the target on the flange. Pairs give A X = X B (A = F_j^-1 F_i,
B = T_j T_i^-1). robocal's own solution is Park and Martin's (rotation from the rotation vectors by an SVD,
translation by least squares); with OpenCV, calibrateHandEye's five methods are run as well and the solution
whose W is most consistent over the images is kept.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.io import opencv_extra
from robocal.model.lie_arrays import skew
from robocal.residuals.camera_model import CameraModel

OPENCV_METHODS = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")


def undistort(camera: CameraModel, k: np.ndarray, uv: np.ndarray, iterations: int = 20) -> np.ndarray:
    """Normalised image coordinates (n, 2) whose projection is uv (Newton on the projection, per point)."""
    uv = np.asarray(uv, dtype=float)
    xy = (uv - k[2:4]) / k[:2]
    for _ in range(iterations):
        X = np.column_stack([xy, np.ones(len(xy))])
        p, dX, _ = camera.project(X, k)
        J = dX[:, :, :2]
        step = np.linalg.solve(J, (uv - p)[:, :, None])[:, :, 0]
        xy = xy + step
        if np.max(np.abs(step)) < 1e-13:
            break
    return xy


def _homography_pose(P: np.ndarray, xy: np.ndarray) -> pin.SE3:
    """Pose of a planar target (z = 0) from normalised points: DLT homography, decomposed (Zhang)."""
    rows = []
    for (X, Y, _), (x, y) in zip(P, xy):
        rows.append([X, Y, 1, 0, 0, 0, -x * X, -x * Y, -x])
        rows.append([0, 0, 0, X, Y, 1, -y * X, -y * Y, -y])
    H = np.linalg.svd(np.array(rows))[2][-1].reshape(3, 3)
    lam = 1.0 / np.linalg.norm(H[:, 0])
    if H[2, 2] * lam < 0:
        lam = -lam                                   # the target in front of the camera
    r1, r2, t = lam * H[:, 0], lam * H[:, 1], lam * H[:, 2]
    U, _, Vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
    R = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    return pin.SE3(R, t)


def _dlt_pose(P: np.ndarray, xy: np.ndarray) -> pin.SE3:
    """Pose of a 3D target from normalised points (at least 6, not coplanar): DLT of [R t]."""
    rows = []
    for X, (x, y) in zip(P, xy):
        Xh = np.append(X, 1.0)
        rows.append(np.concatenate([Xh, np.zeros(4), -x * Xh]))
        rows.append(np.concatenate([np.zeros(4), Xh, -y * Xh]))
    M = np.linalg.svd(np.array(rows))[2][-1].reshape(3, 4)
    U, s, Vt = np.linalg.svd(M[:, :3])
    scale = 1.0 / np.mean(s)
    sign = np.sign(np.linalg.det(U @ Vt))
    R = sign * U @ Vt
    t = sign * scale * M[:, 3]
    if (P @ R.T + t)[:, 2].mean() < 0:
        R, t = -R, -t          # det(-R) = -1: unreachable for a consistent DLT; kept for safety
    return pin.SE3(R, t)


def refine_pose(camera: CameraModel, k: np.ndarray, P: np.ndarray, uv: np.ndarray, T: pin.SE3) -> tuple[pin.SE3, float]:
    """The target pose in the camera minimising the pixel error, from T; and the RMS pixel error there."""
    def fun(v):
        X = P @ pin.exp3(v[3:]).T + v[:3]
        return (camera.project(X, k, derivatives=False) - uv).ravel()

    def jac(v):
        R = pin.exp3(v[3:])
        X = P @ R.T + v[:3]
        _, dX, _ = camera.project(X, k)
        dv = np.concatenate([np.broadcast_to(np.eye(3), (len(P), 3, 3)), -R @ skew(P) @ pin.Jexp3(v[3:])], axis=2)
        return (dX @ dv).reshape(-1, 6)

    v0 = np.concatenate([T.translation, pin.log3(T.rotation)])
    from scipy.optimize import least_squares   # 0.1 s: not at the start-up of every command
    sol = least_squares(fun, v0, jac=jac, method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    rms = float(np.sqrt(np.mean(sol.fun.reshape(-1, 2) ** 2) * 2))
    return pin.SE3(pin.exp3(sol.x[3:]), sol.x[:3].copy()), rms


def solve_pnp(camera: CameraModel, k: np.ndarray, P: np.ndarray, uv: np.ndarray) -> tuple[pin.SE3, float, str]:
    """(target pose in the camera, RMS pixel error, which solver gave the start) of one image's corners."""
    P, uv = np.asarray(P, float), np.asarray(uv, float)
    planar = bool(np.all(np.abs(P[:, 2]) < 1e-12))
    cv2 = opencv_extra.opencv()
    if cv2 is not None and camera.model != "fisheye":
        dist = np.asarray(k[4:], float) if len(k) > 4 else None
        ok, rvec, tvec = cv2.solvePnP(P.astype(np.float64), uv.astype(np.float64), camera.camera_matrix(k), dist)
        if ok:
            return (*refine_pose(camera, k, P, uv, pin.SE3(cv2.Rodrigues(rvec)[0], tvec.reshape(3))), "opencv")
    xy = undistort(camera, k, uv)
    T = _homography_pose(P, xy) if planar else _dlt_pose(P, xy)
    return (*refine_pose(camera, k, P, uv, T), "robocal")


@dataclass
class HandEye:
    X: pin.SE3              # the hand-eye transform (see the module docstring)
    W: pin.SE3              # the constant of F_i X T_i (target in the world, or target on the flange)
    method: str
    spread: tuple[float, float]   # RMS spread of F_i X T_i about W: (m, rad)


def _rotation_mean(Rs: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(Rs.sum(axis=0))
    return U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt


def consistency(F: list[pin.SE3], T: list[pin.SE3], X: pin.SE3) -> tuple[pin.SE3, tuple[float, float]]:
    """W = the mean of F_i X T_i, and the RMS spread about it (m, rad)."""
    Ws = [f * X * t for f, t in zip(F, T)]
    R = _rotation_mean(np.array([w.rotation for w in Ws]))
    p = np.mean([w.translation for w in Ws], axis=0)
    dp = np.sqrt(np.mean([np.sum((w.translation - p) ** 2) for w in Ws]))
    dr = np.sqrt(np.mean([np.sum(pin.log3(R.T @ w.rotation) ** 2) for w in Ws]))
    return pin.SE3(R, p), (float(dp), float(dr))


def park_martin(F: list[pin.SE3], T: list[pin.SE3]) -> pin.SE3:
    """robocal's closed-form X of F_i X T_i = W (all pairs i < j)."""
    A, B = [], []
    for i in range(len(F)):
        for j in range(i + 1, len(F)):
            A.append(F[j].inverse() * F[i])
            B.append(T[j] * T[i].inverse())
    alpha = np.array([pin.log3(a.rotation) for a in A])
    beta = np.array([pin.log3(b.rotation) for b in B])
    U, _, Vt = np.linalg.svd(beta.T @ alpha)        # R beta ~ alpha: Kabsch
    R = Vt.T @ np.diag([1, 1, np.linalg.det(Vt.T @ U.T)]) @ U.T
    C = np.vstack([a.rotation - np.eye(3) for a in A])
    d = np.concatenate([R @ b.translation - a.translation for a, b in zip(A, B)])
    t = np.linalg.lstsq(C, d, rcond=None)[0]
    return pin.SE3(R, t)


def opencv_hand_eye(F: list[pin.SE3], T: list[pin.SE3], method: str) -> pin.SE3:
    """X of F_i X T_i = W by cv2.calibrateHandEye (gripper2base = F_i, target2cam = T_i, cam2gripper = X)."""
    cv2 = opencv_extra.require("calibrateHandEye", what="OpenCV's hand-eye")
    R, t = cv2.calibrateHandEye([f.rotation for f in F], [f.translation.reshape(3, 1) for f in F],
                                [x.rotation for x in T], [x.translation.reshape(3, 1) for x in T],
                                method=getattr(cv2, f"CALIB_HAND_EYE_{method}"))
    U, _, Vt = np.linalg.svd(R)
    return pin.SE3(U @ Vt, np.asarray(t, float).reshape(3))


def hand_eye(F: list[pin.SE3], T: list[pin.SE3]) -> HandEye:
    """The closed-form X with the most consistent W (robocal's Park-Martin and, with OpenCV, its five methods)."""
    if len(F) < 3:
        raise ValueError(f"a closed-form hand-eye needs at least 3 images, got {len(F)}")
    found = {"robocal Park-Martin": park_martin(F, T)}
    if opencv_extra.has("calibrateHandEye"):
        for m in OPENCV_METHODS:
            found[f"OpenCV {m}"] = opencv_hand_eye(F, T, m)
    best = None
    for name, X in found.items():
        if not np.all(np.isfinite(X.homogeneous)):
            continue
        W, spread = consistency(F, T, X)
        # one metre of spread weighs like one radian: both are large next to a sound start
        if best is None or sum(spread) < sum(best.spread):
            best = HandEye(X, W, name, spread)
    return best
