"""Measurement artefacts in the scene, at their estimated value (after) and initial value (before, hidden):
plane (slab), sphere, cylinder (bore), ball bar (fixed ball and bars), laser (beams, fixed point), sphere
artefact (per placement: balls of the certified radius at the fitted centres, bars between the centres).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.residuals.base import basis_from_normal
from robocal.viz import three_objects as three
from robocal.viz.shapes import COLOURS, segment_transform, segments_object


def _at(p) -> np.ndarray:
    return pin.SE3(np.eye(3), np.asarray(p, float)).homogeneous


def draw_artefact(view, b: dict) -> None:
    for s in ("after", "before"):
        a = b.get(f"artefact_{s}")
        if not a:
            continue
        node = view.root["artefacts"][b["name"]][s]
        meas = np.array(b[f"measured_{s}"]).reshape(-1, 3)
        pred = np.array(b[f"predicted_{s}"]).reshape(-1, 3)
        mat = three.MeshLambertMaterial(color=COLOURS["artefact"], opacity=0.45 if s == "after" else 0.2)
        kind = a["kind"]
        if kind == "plane":
            R = basis_from_normal(a["normal"])
            local = (meas - meas.mean(axis=0)) @ R
            span = np.ptp(local[:, :2], axis=0) + 0.1
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R, meas.mean(axis=0)
            node.set_object(three.Box([span[0], span[1], 0.001]), mat)
            node.set_transform(T)
        elif kind == "sphere":
            node.set_object(three.Sphere(a["radius"]), three.MeshLambertMaterial(color=COLOURS["steel"]))
            node.set_transform(_at(a["centre"]))
        elif kind == "cylinder":
            p0, u = np.array(a["point"]), np.array(a["direction"])
            t = (meas - p0) @ u
            node.set_object(three.Cylinder(1.0, 1.0), mat)
            node.set_transform(segment_transform(p0 + (t.min() - 0.05) * u, p0 + (t.max() + 0.05) * u, a["radius"]))
        elif kind == "ball_bar":
            c = np.array(a["centre"])
            node["ball"].set_object(three.Sphere(0.011), three.MeshLambertMaterial(color=COLOURS["steel"]))
            node["ball"].set_transform(_at(c))
            pos = np.column_stack([np.tile(c, (len(pred), 1)), pred]).reshape(-1, 3).T.astype(np.float32)
            node["bars"].set_object(segments_object(pos, colour=0x606060))
        elif kind == "laser_line":
            P, o = np.array(a["target"]), np.array(b[f"beam_origin_{s}"]).reshape(-1, 3)
            node["fixed_point"].set_object(three.Sphere(0.008), three.MeshLambertMaterial(color=COLOURS["laser"]))
            node["fixed_point"].set_transform(_at(P))
            ends = o + 1.15 * (pred - o)
            pos = np.column_stack([o, ends]).reshape(-1, 3).T.astype(np.float32)
            node["beams"].set_object(segments_object(pos, colour=COLOURS["laser"]))
        elif kind == "sphere_artefact":
            _sphere_artefact(node, a, s)
        if s == "before":
            node.set_property("visible", False)


def _sphere_artefact(node, a: dict, state: str) -> None:
    steel = three.MeshLambertMaterial(color=COLOURS["steel"], opacity=0.6 if state == "after" else 0.3)
    bars = []
    for g, centres in enumerate(a["centres"]):
        for j, (c, r) in enumerate(zip(centres, a["radii"])):
            node[f"placement{g}"][f"sphere{j}"].set_object(three.Sphere(r), steel)
            node[f"placement{g}"][f"sphere{j}"].set_transform(_at(c))
        bars += [(centres[j], centres[m]) for j in range(len(centres)) for m in range(j + 1, len(centres))]
    pos = np.array(bars, np.float32).reshape(-1, 3).T
    node["bars"].set_object(segments_object(pos, colour=0x606060))
