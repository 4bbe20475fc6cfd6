"""The robot without meshes: the scene's skeleton (robocal.viz.skeleton_layout) as cylinders and spheres.

A segment whose two ends keep their relative place (within one link, or across a revolute joint) hangs
under its link's node and moves with it; one that changes length or direction from sample to sample (a
prismatic joint, a strut reaching a platform anchor) is a world-level node placed per sample, so its
ends stay on the points they join at every sample.
"""
from __future__ import annotations

import numpy as np

from robocal.viz import three_objects as three
from robocal.viz.shapes import segment_transform

RADIUS = {"link": 1.0, "arm": 0.6, "plate": 0.6}      # times the skeleton's radius
SPHERE = {"joint": 1.6, "closure": 1.4}
TOL = 1e-9


def draw_skeleton(view, name: str, state: str, colour: int, radius: float, opacity: float) -> list[tuple]:
    """Draw the skeleton of one state under /<name>; returns its moving segments [(path, state, ends)]."""
    mat = three.MeshLambertMaterial(color=colour, opacity=opacity)
    sk = view.scene["robot"]["skeleton"][state]
    moving = []
    for k, (a, pa, b, pb, kind) in enumerate(sk["segments"]):
        rel = np.linalg.inv(view.poses(state, a)) @ view.poses(state, b)
        local = rel[:, :3, :3] @ np.asarray(pb, float) + rel[:, :3, 3]     # b's end in a's frame, per sample
        if np.linalg.norm(local - np.asarray(pa, float), axis=1).max() < TOL:
            continue
        geom = three.Cylinder(1.0, RADIUS[kind] * radius)
        if np.abs(local - local[0]).max() < TOL:
            node = view.root[name][a][f"segment{k}"]
            node.set_object(geom, mat)
            node.set_transform(segment_transform(np.asarray(pa, float), local[0]))
        else:
            view.root[name]["moving"][f"segment{k}"].set_object(geom, mat)
            moving.append((f"{name}/moving/segment{k}", state, (a, pa, b, pb)))
    for k, (link, p, kind) in enumerate(sk["spheres"]):
        node = view.root[name][link]["joint" if kind == "joint" else f"{kind}{k}"]     # one joint per link
        node.set_object(three.Sphere(SPHERE[kind] * radius), mat)
        T = np.eye(4)
        T[:3, 3] = p
        node.set_transform(T)
    return moving


def segment_at(view, state: str, sample: int, ends) -> np.ndarray:
    """4x4 of a moving segment at one sample (zero scale when its ends meet)."""
    a, pa, b, pb = ends
    wa = view.pose(state, sample, a) @ np.r_[pa, 1.0]
    wb = view.pose(state, sample, b) @ np.r_[pb, 1.0]
    if np.linalg.norm(wb[:3] - wa[:3]) < TOL:
        T = np.zeros((4, 4))
        T[:3, 3], T[3, 3] = wa[:3], 1.0
        return T
    return segment_transform(wa[:3], wb[:3])
