"""A camera block from detections: checks, per-image PnP, closed-form hand-eye, the residual (docs/camera.md).

`camera_setup` is what a config's camera block (or a Python user) calls: it checks the detections against the
target and the image (errors name the file, line and column), finds each image's target pose (PnP) and refuses
a target seen from behind, solves the hand-eye in closed form on the nominal robot, places the camera (or target)
frame on the robot there, and returns the reprojection residual started at that solution. `camera_problem` then
adds the robot's parameters; `robocal.calibrate` fits everything jointly.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.estimation.camera_init import HandEye, hand_eye, solve_pnp
from robocal.estimation.problem import Problem
from robocal.io.camera_target import CameraTarget
from robocal.io.detections import Detections
from robocal.model.kinematics import ModelState
from robocal.model.parameters import COMPONENTS, ParameterSet, robot_parameters
from robocal.residuals.camera_model import CameraModel
from robocal.residuals.reprojection import ReprojectionResidual

MIN_CORNERS = 6          # a pose from fewer corners is too weak to start from (PnP's minimum is 4 coplanar)
PNP_NOTE_PX = 5.0        # an image whose best pose leaves more than this RMS (px) ...
PNP_NOTE_RATIO = 3.0     # ... and this many times the median image's gets a named note (an outlier image)
MIN_IMAGES = 3           # a closed-form hand-eye needs at least two independent motions


@dataclass
class CameraSetup:
    residual: ReprojectionResidual
    frame: str                      # the robot frame the residual looks at (camera or target)
    attached_to: str                # the robot frame it hangs on
    placement: pin.SE3              # its starting placement relative to `attached_to`
    start: dict[str, float]         # starting values of its placement parameters (non-zero if the URDF had it)
    pnp: dict[int, pin.SE3]         # target in the camera, per reading (index into camera_setup's `values`)
    pnp_rms: dict[int, float]       # px
    hand_eye: HandEye
    notes: list[str] = field(default_factory=list)
    labels: dict[int, str] = field(default_factory=dict)   # sample label of each image, by problem sample index


def sample_index(det: Detections, labels) -> np.ndarray:
    """Sample index (into the joint readings) of every detection; labels: the readings' sample labels."""
    where = {str(lab): i for i, lab in enumerate(labels)}
    out = np.empty(len(det.samples), dtype=int)
    for k, s in enumerate(det.samples):
        if str(s) not in where:
            raise InputError(f"sample {s} has no joint readings (samples: {', '.join(map(str, labels[:5]))}"
                             f"{' ...' if len(labels) > 5 else ''})", source=det.source_of(k), row=det.line(k),
                             field="sample")
        out[k] = where[str(s)]
    return out


def check_detections(det: Detections, target: CameraTarget, camera: CameraModel, min_corners: int = MIN_CORNERS):
    """Every corner id in the target, every pixel in the image, enough corners per image (InputError otherwise)."""
    for k, c in enumerate(det.corners):
        if not target.has(c):
            raise InputError(f"corner id {c} is not on the {target.kind} target (ids {target.ids.min()} to "
                             f"{target.ids.max()}): is the target's geometry the one in the images?",
                             source=det.source_of(k), row=det.line(k), field="corner")
    outside = np.flatnonzero(~camera.inside(det.uv))
    if len(outside):
        k = int(outside[0])
        col = "u" if not -0.5 <= det.uv[k, 0] <= camera.width - 0.5 else "v"
        raise InputError(f"pixel ({det.uv[k, 0]:g}, {det.uv[k, 1]:g}) lies outside the {camera.width} x "
                         f"{camera.height} image ({len(outside)} such rows): check the image size and that u, v are "
                         "pixels", source=det.source_of(k), row=det.line(k), field=col)
    labels, counts = np.unique(det.samples.astype(str), return_counts=True)
    few = [(s, n) for s, n in zip(labels, counts) if n < min_corners]
    if few:
        s, n = few[0]
        k = int(np.flatnonzero(det.samples.astype(str) == s)[0])
        raise InputError(f"sample {s} has {n} corners; at least {min_corners} are needed to place the target in its "
                         f"image ({len(few)} such samples: {', '.join(str(x) for x, _ in few[:5])}); drop their rows "
                         "or lower min_corners", source=det.source_of(k), row=det.line(k), field="corner")


def camera_setup(robot, joint_names, values, labels, det: Detections, target: CameraTarget, camera: CameraModel,
                 intrinsics, *, mount: str = "eye_in_hand", frame: str = "camera", attached_to: str = "tool0",
                 name: str = "camera", sigma: float = 0.5, intrinsics_free=True, intrinsics_prior=None,
                 min_corners: int = MIN_CORNERS, sample_ids=None, groups=None,
                 cache: dict | None = None) -> CameraSetup:
    """The camera block of `det` started at the closed-form solution (module docstring). `values` are the joint
    readings (N, len(joint_names)) in SI, `labels` their sample labels; sample_ids (N,): each reading's sample
    index in the problem the residual goes into (default 0 .. N-1). The frame `frame` is added on `attached_to`
    at the starting placement if the robot has no such frame. Mutates `robot` only so. groups (N,): each
    reading's session when the fixed part (board or camera) was placed anew between sessions; the closed form
    then uses the session with the most images, the others' placements being the sessions' own frames.
    cache: a dict kept between set-ups of the same images (robocal select's rungs): each image's PnP and the
    closed-form hand-eye, keyed by their exact inputs, are solved once (solved_once)."""
    check_detections(det, target, camera, min_corners)
    idx = sample_index(det, labels)
    k = camera.check_intrinsics(intrinsics)
    images = np.unique(idx)
    if len(images) < MIN_IMAGES:
        raise InputError(f"{len(images)} images with detections; a hand-eye calibration needs at least {MIN_IMAGES}",
                         source=det.source, field="sample")
    pnp, rms, notes, behind = {}, {}, [], []
    for i in images:
        rows = np.flatnonzero(idx == i)
        P, uv = np.asarray(target.points_of(det.corners[rows]), float), np.asarray(det.uv[rows], float)
        T, e = solved_once(cache, ("pnp", camera.model, camera.width, camera.height, k.tobytes(), P.tobytes(),
                                   uv.tobytes()), lambda: solve_pnp(camera, k, P, uv)[:2])
        pnp[int(i)], rms[int(i)] = T, e
        if target.planar and T.rotation[2, 2] <= 0:
            behind.append((int(i), int(rows[0])))
    typical = float(np.median(list(rms.values())))
    for i, e in rms.items():
        if e > max(PNP_NOTE_PX, PNP_NOTE_RATIO * typical) and i not in dict(behind):
            notes.append(f"sample {labels[i]}: the best target pose leaves {e:.3g} px RMS (a wrong corner order, target "
                         "geometry or intrinsics, or a blurred image?)")
    if behind:
        raise InputError(f"the target is seen from behind in {len(behind)} image(s) (samples "
                         f"{', '.join(str(labels[i]) for i, _ in behind[:5])}): its printed face points away from "
                         "the camera, so the corner ids run mirrored; check the target's corner numbering "
                         "(docs/camera.md, target frame)", source=det.source_of(behind[0][1]),
                         row=det.line(behind[0][1]), field="corner")
    closed = images
    if groups is not None:          # one fixed placement a session: the closed form within the fullest one
        g = np.asarray(groups)[images]
        closed = images[g == np.bincount(g).argmax()]
        if len(closed) < MIN_IMAGES:
            raise InputError(f"{len(closed)} images in the session with the most; a hand-eye calibration needs at "
                             f"least {MIN_IMAGES} in one session", source=det.source, field="sample")
    nominal = ModelState(robot, ParameterSet(), list(joint_names))
    F = [nominal.sample(values[i]).pose(attached_to) for i in closed]
    T = [pnp[int(i)] for i in closed]
    if mount not in ("eye_in_hand", "eye_to_hand"):
        raise InputError(f"mount must be eye_in_hand or eye_to_hand, got {mount!r}", field="mount")
    # eye-in-hand X: camera on the flange, W: target in the world; eye-to-hand X: camera in the world, W: target
    # on the flange
    A = F if mount == "eye_in_hand" else [f.inverse() for f in F]
    he = solved_once(cache, ("hand_eye", b"".join(a.homogeneous.tobytes() + t.homogeneous.tobytes()
                                                  for a, t in zip(A, T))), lambda: hand_eye(A, T))
    placement, fixed = (he.X, he.W) if mount == "eye_in_hand" else (he.W, he.X)
    start = place_frame(robot, frame, attached_to, placement)
    order = np.argsort(idx, kind="stable")
    ts = None if det.sigma is None else det.sigma[order]
    ids = np.arange(len(values)) if sample_ids is None else np.asarray(sample_ids, dtype=int)
    res = ReprojectionResidual(name, frame, ids[idx[order]], det.uv[order], det.corners[order],
                               target.points_of(det.corners[order]), camera, k, mount=mount, fixed_pose=fixed,
                               intrinsics_free=intrinsics_free, intrinsics_prior=intrinsics_prior, sigma=sigma,
                               term_sigma=ts)
    res.lines = None if det.lines is None else det.lines[order]
    return CameraSetup(res, frame, attached_to, placement, start, pnp, rms, he, notes,
                       {int(ids[i]): str(labels[i]) for i in images})


def solved_once(cache: dict | None, key: tuple, solve):
    """solve(), or what it returned for `key` before: the set-up's solutions depend on their inputs only, which
    the key holds exactly (bytes), so a kept one is the one solve() would give again."""
    if cache is None:
        return solve()
    if key not in cache:
        cache[key] = solve()
    return cache[key]


def place_frame(robot, frame: str, attached_to: str, placement: pin.SE3) -> dict[str, float]:
    """Put `frame` at `placement` relative to `attached_to`: add it if the robot has no such frame (start values
    zero), else return the placement parameters' start values that move it there (they must hang on one link)."""
    if not robot.model.existFrame(frame):
        robot.add_frame(frame, attached_to, placement)
        return {}
    f = robot.model.frames[robot.frame_id(frame)]
    a = robot.model.frames[robot.frame_id(attached_to)]
    if f.parentJoint != a.parentJoint:
        raise InputError(f"frame '{frame}' does not hang on the same link as '{attached_to}'", field="frame")
    delta = pin.log6(f.placement.inverse() * a.placement * placement).vector
    return {f"{frame}.{c}": float(v) for c, v in zip(COMPONENTS, delta)}


def camera_problem(robot, joint_names, values, setup: CameraSetup, preset: str = "offsets",
                   joints: list[str] | None = None, others=()) -> Problem:
    """The joint problem: `preset` over `joints` (default all read joints), the camera (or target) frame's
    placement free, the block's intrinsics and fixed pose as set up; `others`: more residuals."""
    params = robot_parameters(robot, list(joints or joint_names), preset, frames={setup.frame: True})
    params.set_values(setup.start)
    return Problem(robot, params, joint_names, values, [setup.residual, *others])


def hand_eye_of(problem: Problem, setup: CameraSetup) -> pin.SE3:
    """The hand-eye transform at the problem's current values: eye-in-hand the camera frame relative to the frame
    it hangs on; eye-to-hand the camera's pose in the world."""
    res = setup.residual
    if res.mount == "eye_to_hand":
        v = problem.aux_values(res)[res.n_intrinsics:]
        return pin.SE3(pin.exp3(v[3:]), v[:3].copy())
    s = problem.model_state().sample(problem.values[int(res.samples[0])])
    return s.pose(setup.attached_to).inverse() * s.pose(setup.frame)


def separable_hand_eye(robot, params: ParameterSet, joint_names, reading, mount: str, frame: str,
                       attached_to: str = "tool0", fixed: pin.SE3 | None = None) -> pin.SE3:
    """The hand-eye transform as far as camera data can tell it: no image separates the last joint's zero from an
    eye-in-hand camera's turn about that axis, nor the first joint's zero from an eye-to-hand camera's turn about
    the base, so that offset is folded in. Eye-in-hand: the camera relative to `attached_to` at the last joint's
    reading; eye-to-hand: the camera's pose `fixed` relative to the first joint at its reading (docs/camera.md).
    `reading`: any one sample's joint readings (the result does not depend on it)."""
    joints = list(joint_names)
    zeroed = params.copy()
    j = joints[-1] if mount == "eye_in_hand" else joints[0]
    if f"{j}.offset" in zeroed:
        zeroed[f"{j}.offset"].value = 0.0
    s = ModelState(robot, params, joints).sample(reading)
    sz = ModelState(robot, zeroed, joints).sample(reading)
    if mount == "eye_in_hand":
        return sz.pose(attached_to).inverse() * s.pose(frame)
    return (s.pose(attached_to) * sz.pose(attached_to).inverse()).inverse() * fixed
