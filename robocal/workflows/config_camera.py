"""A `type: camera` block of the calibration config: its keys read and checked, and its residual set up.

    - type: camera
      name: camera
      frame: camera               # the camera (eye_in_hand) or the target (eye_to_hand) on the robot
      attached_to: tool0          # the frame it hangs on (default tool0)
      mount: eye_in_hand          # or eye_to_hand
      detections: detections.csv  # sample, corner, u, v[, sigma] (robocal.io.detections); or a list of files
      target: {type: checkerboard, corners: [9, 6], square: 0.03}      # robocal.io.camera_target
      camera: {model: plumb_bob, image_size: [1280, 1024], intrinsics: [fx, fy, cx, cy, k1, k2, p1, p2, k3],
               free: true, prior: {fx: 5.0}}                            # robocal.residuals.camera_model
      sigma: 0.3                  # px per corner coordinate (default 0.5)
      min_corners: 6              # an image with fewer corners is refused
      world_pose: {xyz: [..], rpy: [..]}   # robocal plan only: the target (camera) in the world

The rows of the joint-readings table the block reads are its images; a detection's `sample` names its row by
the table's `sample` column, or by the 1-based row number without one. The set-up (camera_setup: checks, PnP,
closed-form hand-eye) adds the frame to the robot when the robot has none of that name, so it runs before the
parameters are made; the frame's placement is then free and starts at the closed form (docs/camera.md).
With sessions, the images of every session come from the detections files (one, or a list: one a session, say),
their labels distinct.
Scoring other images (robocal evaluate): camera_detections names each block's new detections file, and
with_camera_frames_of starts the camera frame where the fit started it.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.estimation.camera_block import MIN_CORNERS, CameraSetup, camera_setup
from robocal.io.camera_target import target_from_dict
from robocal.io.detections import read_detections_files
from robocal.io.tables import Table
from robocal.residuals.camera_model import camera_spec_from_dict
from robocal.residuals.reprojection import MOUNTS
from robocal.workflows.config_keys import Cfg
from robocal.workflows.config_types import CameraBlockConfig, FrameSpec, MeasurementConfig, Placement

#: a camera block's sigma when it gives none (px per corner coordinate)
DEFAULT_SIGMA = 0.5
#: the joint table's column that labels the images (else the 1-based row number)
SAMPLE_COLUMN = "sample"


def camera_block_config(b: Cfg, base_dir: Path, placement) -> tuple[CameraBlockConfig, float]:
    """(the camera keys of block `b`, its sigma in px); target and camera mappings checked here (their errors
    name the key), the detections file when the set-up reads it. placement: config_read's xyz/rpy reader."""
    mount = b.get("mount", "eye_in_hand", types=str)
    if mount not in MOUNTS:
        raise b.error(f"mount must be one of {', '.join(MOUNTS)}, got {mount!r}", "mount")
    target = b.get("target", required=True, types=dict)
    target_from_dict(target, b.source, b.where("target"))
    camera = b.get("camera", required=True, types=dict)
    camera_spec_from_dict(camera, b.source, b.where("camera"))
    min_corners = b.get("min_corners", MIN_CORNERS, types=int)
    if min_corners < 4:
        raise b.error(f"a target pose needs at least 4 corners, got {min_corners}", "min_corners")
    sigma = b.get("sigma", DEFAULT_SIGMA, types=(int, float))
    if not (np.isfinite(sigma) and sigma > 0):
        raise b.error(f"a pixel sigma must be a positive number, got {sigma!r}", "sigma")
    detections = b.get("detections", types=(str, list))
    if isinstance(detections, list):     # several files (a session's images each), read as one
        if not detections or not all(isinstance(f, str) for f in detections):
            raise b.error("detections: a file name, or a list of file names", "detections")
        detections = tuple((base_dir / f).resolve() for f in detections)
    elif detections is not None:
        detections = (base_dir / detections).resolve()
    world = b.child("world_pose")
    return CameraBlockConfig(b.get("attached_to", "tool0", types=str), mount,
                             detections, target, camera,
                             min_corners, None if world.value is None else placement(world)), float(sigma)


def block_frame_exists(robot, m: MeasurementConfig) -> None:
    """A camera block's frame may be one the set-up adds; its attached_to must be on the robot."""
    try:
        robot.frame_id(m.camera.attached_to)
    except InputError as exc:
        raise InputError(exc.reason, source=exc.source, field=f"{m.path}.attached_to") from None


def image_labels(tab: Table, rows) -> list[str]:
    """The label of each row the block reads: the `sample` column, else the 1-based row number."""
    if tab.has(SAMPLE_COLUMN):
        j = tab.header.index(SAMPLE_COLUMN)
        return [tab.cells[int(r)][j].strip() for r in rows]
    return [str(int(r) + 1) for r in rows]


def camera_residual(robot, m: MeasurementConfig, source: str, joint_names, values: np.ndarray, labels,
                    sample_ids, sessions: np.ndarray | None, camera_cache: dict | None = None) -> CameraSetup:
    """Set up one camera block over its images: values (N, n_joints) SI, labels, sample_ids in the problem;
    sessions (N,): each image's session (the board or camera placed anew in each), None for one session."""
    cam = m.camera
    if sessions is not None:
        seen = {}
        for lab, s in zip(labels, sessions):
            if seen.setdefault(lab, s) != s:
                raise InputError(f"image label {lab!r} is in two sessions: the detections name images by label, so "
                                 "with sessions the labels must differ between them (a `sample` column)",
                                 source=source, field=f"{m.path}.detections")
    if cam.detections is None:
        raise InputError("required key is missing (the detections CSV: sample, corner, u, v)", source=source,
                         field=f"{m.path}.detections")
    paths = cam.detections if isinstance(cam.detections, tuple) else (cam.detections,)
    for k, path in enumerate(paths):
        if not path.is_file():
            raise InputError(f"detections file not found: {path}", source=source,
                             field=f"{m.path}.detections" + (f"[{k}]" if len(paths) > 1 else ""))
    det = read_detections_files(paths)
    target = target_from_dict(cam.target, source, f"{m.path}.target")
    spec = camera_spec_from_dict(cam.camera, source, f"{m.path}.camera")
    return camera_setup(robot, joint_names, values, labels, det, target, spec.model, spec.intrinsics,
                        mount=cam.mount, frame=m.frame, attached_to=cam.attached_to, name=m.name,
                        sigma=float(m.sigma), intrinsics_free=spec.free, intrinsics_prior=spec.prior,
                        min_corners=cam.min_corners, sample_ids=sample_ids, groups=sessions, cache=camera_cache)



def camera_detections(config, given: dict | None) -> dict[str, Path]:
    """{camera block name: detections file} for scoring other images (robocal evaluate): every camera block of
    `config` needs one; a key None names the only camera block."""
    blocks = [m for m in config.measurements if m.camera is not None]
    given = dict(given or {})
    if None in given:
        if len(blocks) != 1:
            raise InputError(f"--detections FILE without a block name needs exactly one camera block; this config has "
                             f"{len(blocks)}: give NAME=FILE", source=config.source, field="--detections")
        given[blocks[0].name] = given.pop(None)
    names = {m.name for m in blocks}
    unknown = sorted(set(given) - names)
    if unknown:
        raise InputError(f"no camera block named {', '.join(unknown)} (camera blocks: "
                         f"{', '.join(sorted(names)) or 'none'})", source=config.source, field="--detections")
    missing = [m for m in blocks if m.name not in given]
    if missing:
        raise InputError(f"camera block '{missing[0].name}' scores the new images from their own detections: pass "
                         "--detections FILE (sample, corner, u, v; the samples named as in the new CSV)",
                         source=config.source, field=f"{missing[0].path}.detections")
    return {n: Path(f).resolve() for n, f in given.items()}


def with_detections(config, detections: dict[str, Path]):
    """The config with the detections file of each named camera block replaced."""
    measurements = [dataclasses.replace(m, camera=dataclasses.replace(m.camera, detections=detections[m.name]))
                    if m.camera is not None and m.name in detections else m for m in config.measurements]
    return dataclasses.replace(config, measurements=measurements)


def with_camera_frames_of(config, setup):
    """The config with each frame a camera set-up of `setup` (the training data's) added to its robot made a frame
    of the `robot:` section, at that closed-form start: a fit's frame parameters are corrections of that start,
    so another session's set-up must start from it, not from its own closed form. A frame the robot already had
    (its URDF's, or the config's) is its own start and stays as it is."""
    robot, added = setup.problem.robot, []
    for m in config.measurements:
        cam = setup.cameras.get(m.name) if m.camera is not None else None
        if cam is None or cam.start:      # start: the corrections that move an existing frame to the closed form
            continue
        frame = robot.model.frames[robot.frame_id(m.frame)]
        parent = robot.model.frames[robot.frame_id(m.camera.attached_to)]
        rel = parent.placement.inverse() * frame.placement
        xyz, rpy = tuple(rel.translation.tolist()), tuple(pin.rpy.matrixToRpy(rel.rotation).tolist())
        added.append(FrameSpec(m.frame, m.camera.attached_to, Placement(xyz, rpy)))
    if not added:
        return config
    return dataclasses.replace(config, robot=dataclasses.replace(config.robot, frames=(*config.robot.frames, *added)))


def refuse_camera_blocks(config, command: str, why: str) -> None:
    """InputError naming the first camera block of `config` for a command that cannot take one."""
    for m in config.measurements:
        if m.camera is not None:
            raise InputError(f"robocal {command} does not take camera blocks: {why}", source=config.source,
                             field=f"{m.path}.type")
