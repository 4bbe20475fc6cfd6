"""A camera block in the scene file (robocal.viz.scene, version 3): what the 3D check and the report draw.

3D points of a term (what the scene's generic measured / predicted points and residual arrows show):
  predicted  the target's corner in the world at the model's values;
  measured   the point on the detected pixel's ray (undistorted, from the camera's centre) at the corner's depth,
             so the arrow between them is the reprojection error carried to the target (px x depth / focal).
The block's `camera` entry adds what a camera drawing needs (SI, px):
  mount, model, image_size, intrinsics_{before,after}, fixed_{before,after} (pose7 of the target in the world,
  eye-in-hand, or of the camera in the world, eye-to-hand), corner_ids and corner_points (the target's corners in
  its frame), pixels (the detected u, v of every term, in term order). The reprojected pixels are pixels +
  residual_{state} (the block's residual rows are predicted - detected, px).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.estimation.camera_init import undistort
from robocal.residuals.reprojection import pose_of

STATES = ("before", "after")


def _pose7(M: pin.SE3) -> list[float]:
    return [*M.translation.tolist(), *pin.Quaternion(M.rotation).coeffs().tolist()]


def camera_and_target(res, M: pin.SE3, aux) -> tuple[pin.SE3, pin.SE3]:
    """(camera in the world, target in the world) at one sample: M the residual frame's world pose."""
    fixed = pose_of(aux[res.n_intrinsics:])
    return (M, fixed) if res.mount == "eye_in_hand" else (fixed, M)


def undistorted(res, aux) -> np.ndarray:
    """Normalised image coordinates (n_terms, 2) of every detected pixel: one whole-array Newton solve (per point
    it cost ~0.5 ms, 1 s for the camera example's 2 x 2160 terms)."""
    return undistort(res.camera, np.asarray(aux[:res.n_intrinsics], float), res.measurements)


def camera_points(res, k: int, M: pin.SE3, aux, xy=None) -> tuple[np.ndarray, np.ndarray]:
    """(measured (1, 3), predicted (1, 3)) world points of term k (module docstring); xy: row k of
    `undistorted(res, aux)`, None to undistort this pixel alone."""
    C, T = camera_and_target(res, M, aux)
    corner = T.act(res.points[k])
    depth = (C.actInv(corner))[2]
    if xy is None:
        xy = undistort(res.camera, np.asarray(aux[:res.n_intrinsics], float), res.measurements[k:k + 1])[0]
    return C.act(depth * np.array([xy[0], xy[1], 1.0]))[None, :], corner[None, :]


def camera_entry(res, param_aux: dict[str, np.ndarray]) -> dict:
    """The block's `camera` entry; param_aux: {state: the residual's auxiliary values}."""
    ids, first = np.unique(res.corners, return_index=True)
    out = {"mount": res.mount, "model": res.camera.model, "image_size": [res.camera.width, res.camera.height],
           "corner_ids": ids.tolist(), "corner_points": res.points[first].tolist(),
           "pixels": res.measurements.tolist()}
    for s in STATES:
        aux = param_aux[s]
        out[f"intrinsics_{s}"] = np.asarray(aux[:res.n_intrinsics], float).tolist()
        out[f"fixed_{s}"] = _pose7(pose_of(aux[res.n_intrinsics:]))
    return out
