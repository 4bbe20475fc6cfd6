"""A camera block in the meshcat check: the camera's frustum, the target, and the current image's rays.

Drawn under /meshcat/robocal/camera/<block>/ (after calibration):
  frustum     the image's four corners seen from the camera's centre, out to the median corner distance
  target      the board (a thin slab over its corners) and its corners
  rays/<i>    sample i's rays: from the camera's centre through each detected pixel to the corner's depth (shown
              with sample i only); the generic measured / predicted points and residual arrows sit at their ends
The camera (eye-in-hand) or the target (eye-to-hand) moves with the robot frame; the other stays where the fit put
it (the block's `camera` entry, robocal.viz.camera_scene).
"""
from __future__ import annotations

from robocal.viz import three_objects as mg   # meshcat's object commands without its Python package
import numpy as np
import pinocchio as pin

from robocal.viz.shapes import COLOURS, se3_from_pose7, segments_object

BOARD_COLOUR, FRUSTUM_COLOUR, RAY_COLOUR = 0xf0f0e0, 0x606060, 0x303030


def _moving(b: dict) -> str:
    """Which of camera / target moves with the robot frame."""
    return "frustum" if b["camera"]["mount"] == "eye_in_hand" else "target"


def _terms_of(b: dict, sample: int) -> np.ndarray:
    return np.array([k for k, t in enumerate(b["terms"]) if sample in t], dtype=int)


def frustum_depth(view, b: dict) -> float:
    """Median distance from the camera's centre to the corners it saw (m)."""
    cam = b["camera"]
    pts = np.array(b["predicted_after"]).reshape(-1, 3)
    if cam["mount"] == "eye_in_hand":
        centres = np.array([view.pose("after", int(t[0]), b["frame"])[:3, 3] for t in b["terms"]])
    else:
        centres = np.broadcast_to(se3_from_pose7(cam["fixed_after"]).translation, pts.shape)
    return float(np.median(np.linalg.norm(pts - centres, axis=1))) if len(pts) else 0.5


def draw_camera(view, b: dict) -> None:
    """Frustum, target and per-sample rays of a camera block (module docstring)."""
    cam = b["camera"]
    node = view.root["camera"][b["name"]]
    fx, fy, cx, cy = cam["intrinsics_after"][:4]
    w, h = cam["image_size"]
    d = frustum_depth(view, b)
    corners = np.array([[(u - cx) / fx * d, (v - cy) / fy * d, d] for u, v in ((0, 0), (w, 0), (w, h), (0, h))])
    pos = np.vstack([np.vstack([np.zeros(3), c]) for c in corners]
                    + [np.vstack([corners[i], corners[(i + 1) % 4]]) for i in range(4)])
    node["frustum"].set_object(segments_object(pos.T.astype(np.float32), colour=FRUSTUM_COLOUR))
    P = np.array(cam["corner_points"])
    lo, hi = P.min(axis=0), P.max(axis=0)
    margin = 0.1 * max(np.ptp(P[:, 0]), np.ptp(P[:, 1]), 0.01)
    board = node["target"]["board"]
    board.set_object(mg.Box([hi[0] - lo[0] + 2 * margin, hi[1] - lo[1] + 2 * margin, 0.001]),
                     mg.MeshLambertMaterial(color=BOARD_COLOUR, opacity=0.7))
    centre = (lo + hi) / 2 + np.array([0, 0, 0.0006])      # the printed face at z = 0, the slab behind it
    board.set_transform(pin.SE3(np.eye(3), centre).homogeneous)
    node["target"]["corners"].set_object(mg.Points(mg.PointsGeometry(P.T.astype(np.float32)),
                                                   mg.PointsMaterial(size=0.004, color=COLOURS["measured"])))
    fixed = se3_from_pose7(cam["fixed_after"]).homogeneous
    node["target" if _moving(b) == "frustum" else "frustum"].set_transform(fixed)
    measured = np.array(b["measured_after"]).reshape(-1, 3)
    for i in sorted({int(s) for t in b["terms"] for s in t}):
        terms = _terms_of(b, i)
        C = (view.pose("after", i, b["frame"]) if cam["mount"] == "eye_in_hand" else fixed)[:3, 3]
        rays = np.vstack([np.vstack([C, p]) for p in measured[terms]])
        node["rays"][str(i)].set_object(segments_object(rays.T.astype(np.float32), colour=RAY_COLOUR))


def camera_commands(view, b: dict, sample: int, base: str) -> tuple[dict, dict]:
    """(transforms, visibilities) that show one sample: the moving part at the frame's pose, that sample's rays."""
    path = f"{base}/camera/{b['name']}"
    T = {f"{path}/{_moving(b)}": view.pose("after", sample, b["frame"])}
    samples = {int(s) for t in b["terms"] for s in t}
    V = {f"{path}/rays/{i}": i == sample for i in samples}
    return T, V
