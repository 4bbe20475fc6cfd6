"""Measurements in the scene: points, residual arrows, pose triads, the current sample's marker.

Pose blocks also get triads at each measured position: the measured orientation (axes red, green, blue)
and the prediction after (blue) and before (orange, hidden) with its rotation error magnified by a round
factor, so that the rotation residual shows as the angle between the measured and predicted axes.
"""
from __future__ import annotations

import numpy as np

from robocal.viz import three_objects as three
from robocal.viz.shapes import (COLOURS, points_object, segments_object, arrows, colour_scale, magnified_rotations,
                         nice_factor, quat_rotations, triads)

TRIAD_ANGLE = 0.35           # rad: the largest rotation residual is drawn about 20 degrees
TRIAD_FRACTION = 0.04        # triad length, fraction of the scene's size
AXES = np.array([[0.85, 0.1, 0.1], [0.1, 0.65, 0.1], [0.1, 0.2, 0.85]])


def rotation_errors(b: dict, state: str) -> np.ndarray:
    """(terms,) angle (rad) between the predicted and measured orientation of a pose block."""
    return np.linalg.norm(np.array(b[f"residual_{state}"])[:, 3:6], axis=1)


def rotation_scale(blocks: list[dict], state: str) -> tuple[float, float]:
    """(largest rotation residual, its magnification) over the pose blocks; the factor is at least 1."""
    mx = max([rotation_errors(b, state).max() for b in blocks if b["type"] == "pose" and b["residual_after"]]
             + [0.0])
    return float(mx), (max(1.0, nice_factor(TRIAD_ANGLE / mx)) if mx > 0 else 1.0)


def draw_measurements(view, b: dict) -> None:
    node = view.root["measurements"][b["name"]]
    meas = np.array(b["measured_after"]).reshape(-1, 3)
    if not len(meas):
        return
    size = 0.006 * max(view.size, 0.5)
    node["measured"].set_object(points_object(meas, COLOURS["measured"], size))
    for s in ("before", "after"):
        m = np.array(b[f"measured_{s}"]).reshape(-1, 3)
        p = np.array(b[f"predicted_{s}"]).reshape(-1, 3)
        node[f"predicted_{s}"].set_object(points_object(p, COLOURS[s], size))
        err = np.linalg.norm(p - m, axis=1)
        pos, col = arrows(m, view.arrow_scale[s] * (p - m), colour_scale(err, view.arrow_max[s]))
        if pos.size:
            node[f"residual_{s}"].set_object(segments_object(pos, col))
    node["predicted_before"].set_property("visible", False)
    if b["type"] == "pose":
        _pose_triads(view, node, b, meas)
    view.root["current"][b["name"]].set_object(three.Sphere(0.012 * max(view.size, 0.5)),
                                               three.MeshLambertMaterial(color=COLOURS["current"], opacity=0.5))


def _pose_triads(view, node, b: dict, origins: np.ndarray) -> None:
    length = TRIAD_FRACTION * view.size
    R_meas = quat_rotations(b["measured_orientation"])
    node["triad_measured"].set_object(segments_object(*triads(origins, R_meas, length, AXES)))
    for s in ("before", "after"):
        R = magnified_rotations(quat_rotations(b[f"orientation_{s}"]), R_meas, view.rotation_scale[s])
        colour = np.tile(np.array([(COLOURS[s] >> k) & 255 for k in (16, 8, 0)]) / 255.0, (3, 1))
        node[f"triad_{s}"].set_object(segments_object(*triads(origins, R, length, colour)))
    node["triad_before"].set_property("visible", False)


def current_point(b: dict, sample: int) -> np.ndarray | None:
    """Where the current-sample marker goes: the mean of a one-sample term's points, or this sample's
    own point in a term over several samples (a sphere-artefact placement); None when not measured."""
    found = []          # a camera image has one term per corner: the marker goes to their mean
    for k, term in enumerate(b["terms"]):
        if sample not in term or k >= len(b["measured_after"]):
            continue
        pts = np.array(b["measured_after"][k]).reshape(-1, 3)
        if len(term) > 1:
            return pts[term.index(sample)]
        found.append(pts)
    return np.vstack(found).mean(axis=0) if found and len(np.vstack(found)) else None


def label_parts(b: dict, sample: int) -> list[str]:
    """'block: |r| before -> after mm' for each term of the block that uses the sample (length rows); a camera
    block: 'block: RMS before -> after px (n corners)' over the sample's corners."""
    if "camera" in b:
        terms = [k for k, term in enumerate(b["terms"]) if sample in term]
        if not terms:
            return []
        r0, r1 = (np.sqrt(np.mean(np.sum(np.array(b[f"residual_{s}"])[terms] ** 2, axis=1)))
                  for s in ("before", "after"))
        return [f"{b['name']}: RMS {r0:.3g} -> {r1:.3g} px ({len(terms)} corners)"]
    length = np.array(b["row_units"]) == "length"     # mm only: pose blocks also hold angles
    out = []
    for k, term in enumerate(b["terms"]):
        if sample in term:
            r0, r1 = (np.linalg.norm(np.array(b[f"residual_{s}"][k])[length]) for s in ("before", "after"))
            out.append(f"{b['name']}: |r| {1e3 * r0:.3g} -> {1e3 * r1:.3g} mm")
    return out
