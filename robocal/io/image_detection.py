"""Corners of a camera target found in images, with OpenCV (the optional extra), written as a detections CSV.

checkerboard: cv2.findChessboardCorners then cornerSubPix (ids in OpenCV's order, robocal.io.camera_target);
charuco: cv2.aruco.CharucoDetector (its corner ids); aruco_grid (AprilTag dictionaries too): cv2.aruco.ArucoDetector,
corner id 4 * marker id + k. Images are read with cv2.imread; an image where the target is not found is left out
and named in the returned notes. Sample labels are the images' file stems unless given. See docs/camera.md.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from robocal.errors import InputError
from robocal.io import opencv_extra
from robocal.io.camera_target import CameraTarget
from robocal.io.detections import Detections


def detect_corners(image: np.ndarray, target: CameraTarget) -> tuple[np.ndarray, np.ndarray]:
    """(corner ids (n,), pixels (n, 2)) of `target` in one grey or colour image (empty when not found)."""
    cv2 = opencv_extra.require("aruco.CharucoDetector", "findChessboardCorners", what="corner detection")
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    none = (np.zeros(0, int), np.zeros((0, 2)))
    lay = target.layout
    if target.kind == "checkerboard":
        found, corners = cv2.findChessboardCorners(grey, tuple(lay["corners"]))
        if not found:
            return none
        corners = cv2.cornerSubPix(grey, corners, (5, 5), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3))
        return np.arange(len(corners)), corners.reshape(-1, 2).astype(float)
    if target.kind not in ("charuco", "aruco_grid"):
        raise InputError(f"no image detector for a '{target.kind}' target (checkerboard, charuco, aruco_grid)",
                         field="target.type")
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, lay["dictionary"]))
    if target.kind == "charuco":
        board = cv2.aruco.CharucoBoard(tuple(lay["squares"]), lay["square"], lay["marker"], dictionary)
        corners, ids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(grey)
        if ids is None:
            return none
        return ids.reshape(-1).astype(int), corners.reshape(-1, 2).astype(float)
    corners, ids, _ = cv2.aruco.ArucoDetector(dictionary).detectMarkers(grey)
    if ids is None:
        return none
    out_ids = np.concatenate([4 * int(i) + np.arange(4) for i in ids.reshape(-1)])
    keep = np.array([target.has(c) for c in out_ids], bool)     # markers of other boards in view
    return out_ids[keep], np.vstack([c.reshape(4, 2) for c in corners]).astype(float)[keep]


def detect_images(paths, target: CameraTarget, labels=None, min_corners: int = 6) -> tuple[Detections, list[str]]:
    """Detections of every image (label: the file stem, or `labels`), and notes naming the images left out."""
    cv2 = opencv_extra.require("imread", what="reading images")
    paths = [Path(p) for p in paths]
    labels = [p.stem for p in paths] if labels is None else [str(x) for x in labels]
    samples, ids, uv, notes = [], [], [], []
    for path, label in zip(paths, labels):
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise InputError("not an image OpenCV can read", source=str(path))
        c, p = detect_corners(image, target)
        if len(c) < min_corners:
            notes.append(f"{path.name}: {len(c)} corners of the target found (fewer than {min_corners}); left out")
            continue
        samples += [label] * len(c)
        ids.append(c)
        uv.append(p)
    if not ids:
        raise InputError(f"the target was found in none of the {len(paths)} images", source=str(paths[0].parent)
                         if paths else None)
    return Detections("images", np.array(samples, dtype=object), np.concatenate(ids), np.vstack(uv)), notes
