"""Candidate poses for a camera calibration: joint readings that keep the whole target in view (docs/camera.md).

Viewpoints are drawn where a camera sees a planar target well (eye-in-hand: the camera on a cap in front of the
fixed target, looking at a point near its centre; eye-to-hand: the target on the flange, in front of the fixed
camera, turned towards it), each with a random roll, and reached by inverse kinematics on the nominal robot from a
seed reading (the previous solutions serve as further seeds). A candidate is kept when IK converges within the
joint limits, every corner projects into the image with a margin, and the target faces the camera within
`max_tilt`. `camera_design_problem` then gives robocal.design.selection the Jacobian of every candidate, and
`simulate_detections` the corners a camera would detect at given readings (tests, examples, benchmarks).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robocal.errors import RobocalError
from robocal.estimation.problem import Problem
from robocal.io.camera_target import CameraTarget
from robocal.io.detections import Detections
from robocal.model.inverse_kinematics import solve_ik
from robocal.model.kinematics import ModelState
from robocal.model.parameters import ParameterSet, robot_parameters
from robocal.residuals.camera_model import CameraModel
from robocal.residuals.reprojection import ReprojectionResidual, pose_vector


@dataclass
class CameraView:
    """Where the target is seen from: the range of distances (m), the largest tilt (rad), the pixel margin."""

    distance: tuple[float, float] = (0.3, 0.6)
    max_tilt: float = np.radians(40.0)
    margin: float = 20.0
    aim_jitter: float = 0.3          # of the target size: how far from its centre the camera aims


@dataclass
class CameraCandidates:
    values: np.ndarray                               # (K, n_joints) kept readings
    dropped: dict[str, int] = field(default_factory=dict)


def look_at(eye: np.ndarray, aim: np.ndarray, roll: float) -> np.ndarray:
    """Rotation of a camera at `eye` whose optical axis (z) points at `aim`, turned by `roll` about it."""
    z = (aim - eye) / np.linalg.norm(aim - eye)
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    R = np.column_stack([x, np.cross(z, x), z])
    return R @ pin.exp3(np.array([0, 0, roll]))


def _tilted(rng, max_tilt) -> np.ndarray:
    """A unit vector within max_tilt of +z, uniform on the cap."""
    c = rng.uniform(np.cos(max_tilt), 1.0)
    a = rng.uniform(-np.pi, np.pi)
    s = np.sqrt(1 - c * c)
    return np.array([s * np.cos(a), s * np.sin(a), c])


def in_view(camera: CameraModel, k, X: np.ndarray, facing: float, view: CameraView) -> bool:
    """Every corner X (camera frame) in front and inside the image with the margin; the target turned towards
    the camera (facing: cosine between the optical axis and the target's z) within the largest tilt."""
    if np.any(X[:, 2] <= 0) or facing < np.cos(view.max_tilt + np.radians(10)):
        return False
    return bool(np.all(camera.inside(camera.project(X, k, derivatives=False), view.margin)))


def camera_candidates(robot, joint_names, frame: str, mount: str, fixed: pin.SE3, target: CameraTarget,
                      camera: CameraModel, k, n: int, rng: np.random.Generator, seed, view: CameraView | None = None,
                      tries: int | None = None) -> CameraCandidates:
    """Up to `n` readings that keep the target in view (module docstring). `frame` is the camera (eye-in-hand)
    or the target (eye-to-hand) on the robot, `fixed` the world pose of the other; `seed` a reading near them."""
    view = view or CameraView()
    ms = ModelState(robot, ParameterSet(), list(joint_names))
    lo, hi = robot.limits(list(joint_names))
    centre = target.points.mean(axis=0)
    seeds = [np.asarray(seed, dtype=float)]
    kept, dropped = [], {"IK failed": 0, "target not in view": 0}
    for _ in range(tries or 20 * n):
        if len(kept) >= n:
            break
        d = rng.uniform(*view.distance)
        roll = rng.uniform(-np.pi, np.pi)
        jitter = rng.uniform(-1, 1, 2) * view.aim_jitter * target.size / 2
        if mount == "eye_in_hand":            # camera on a cap in front of the printed face (target -z side)
            aim = fixed.act(centre + np.array([*jitter, 0.0]))
            eye = fixed.act(centre - d * _tilted(rng, view.max_tilt))
            goal = pin.SE3(look_at(eye, aim, roll), eye)
        else:                                 # target in front of the fixed camera, facing it
            ray = _tilted(rng, 0.5 * np.arctan(min(camera.width, camera.height) / (2 * k[0])))
            R_ct = look_at(np.zeros(3), _tilted(rng, view.max_tilt), roll)   # target z within the tilt of the axis
            p_ct = ray / ray[2] * d - R_ct @ centre
            goal = fixed * pin.SE3(R_ct, p_ct)
        v = None
        # a kept reading first (its branch), then random readings within the limits (another branch)
        for start in (seeds[rng.integers(len(seeds))], rng.uniform(lo, hi), rng.uniform(lo, hi)):
            try:
                v = solve_ik(ms, frame, goal, start, lower=lo, upper=hi, tol=1e-10, max_iterations=100, max_step=0.3)
                break
            except RobocalError:
                continue
        if v is None:
            dropped["IK failed"] += 1
            continue
        M = ms.sample(v).pose(frame)
        C, T = (M, fixed) if mount == "eye_in_hand" else (fixed, M)
        rel = C.inverse() * T
        if not in_view(camera, k, target.points @ rel.rotation.T + rel.translation, rel.rotation[2, 2], view):
            dropped["target not in view"] += 1
            continue
        kept.append(v)
        seeds.append(v)
    return CameraCandidates(np.array(kept).reshape(-1, len(joint_names)), dropped)


def camera_design_problem(robot, joint_names, candidates, frame: str, mount: str, fixed: pin.SE3,
                          target: CameraTarget, camera: CameraModel, k, preset: str = "offsets",
                          sigma: float = 0.5, intrinsics_free=True, name: str = "camera", intrinsics_prior=None,
                          joints=None) -> Problem:
    """A problem with every corner of the target seen at every candidate (placeholder pixels; the design predicts
    them), the robot's `preset` over `joints` (default all of joint_names), the frame's placement, the intrinsics
    (free as `intrinsics_free` says, with `intrinsics_prior`) and the fixed pose free: what
    robocal.design.selection.DesignMatrix.from_problem needs."""
    n_c = len(target.ids)
    samples = np.repeat(np.arange(len(candidates)), n_c)
    res = ReprojectionResidual(name, frame, samples, np.zeros((len(samples), 2)), np.tile(target.ids, len(candidates)),
                               np.tile(target.points, (len(candidates), 1)), camera, k, mount=mount,
                               fixed_pose=pose_vector(fixed), intrinsics_free=intrinsics_free,
                               intrinsics_prior=intrinsics_prior, sigma=sigma)
    params = robot_parameters(robot, list(joints or joint_names), preset, frames={frame: True})
    return Problem(robot, params, list(joint_names), np.asarray(candidates, dtype=float), [res])


def simulate_detections(robot, params: ParameterSet, joint_names, values, frame: str, mount: str, fixed: pin.SE3,
                        target: CameraTarget, camera: CameraModel, k, noise: float, rng: np.random.Generator,
                        labels=None) -> Detections:
    """The corners seen at each reading on the robot `params` describe (the truth), with Gaussian pixel noise
    (px); `frame` is the camera (eye-in-hand) or the target (eye-to-hand) on the robot, `fixed` the world pose of
    the other. Corners behind the camera or outside the image are not detected. Sample labels: `labels`, else
    1, 2, ... (the joint table's row numbers)."""
    ms = ModelState(robot, params, list(joint_names))
    labels = [str(i + 1) for i in range(len(values))] if labels is None else [str(x) for x in labels]
    samples, corners, uv = [], [], []
    for lab, v in zip(labels, np.atleast_2d(values)):
        M = ms.sample(v).pose(frame)
        rel = M.inverse() * fixed if mount == "eye_in_hand" else fixed.inverse() * M
        X = target.points @ rel.rotation.T + rel.translation
        px = camera.project(X, k, derivatives=False) + rng.normal(0, noise, (len(X), 2))
        seen = (X[:, 2] > 0) & camera.inside(px)
        samples += [lab] * int(seen.sum())
        corners.append(target.ids[seen])
        uv.append(px[seen])
    return Detections("simulated", np.array(samples, dtype=object), np.concatenate(corners), np.vstack(uv))
