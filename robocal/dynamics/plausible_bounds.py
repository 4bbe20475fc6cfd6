"""Plausible bodies: each body's mass within a band around its CAD mass and its mass inside a bounding
ellipsoid of its geometry, as linear constraints on the 10 inertial parameters.

Realisable (pseudo-inertia J PSD, inertial.py) admits a 1 g torso or a body whose mass sits metres from
its joint. Density realisability on an ellipsoid E = {x : (x - c)^T A (x - c) <= 1} (Wensing, Kim and
Slotine 2017) adds tr(Q J) >= 0 with Q = [[-A, A c], [c^T A, 1 - c^T A c]]: tr(Q J) is the integral of
1 - (x - c)^T A (x - c) over the mass, non-negative when all of it lies in E (together with J PSD
necessary and sufficient on an ellipsoid). It bounds the centre of mass and, for a given mass, the
inertia. Both constraints are linear in the parameters, so the consistent fit stays one convex problem.

The ellipsoid of a body (the reduced model's body: its URDF link, the links fixed to it and the locked
subtrees) comes, in this order, from the config (model.plausible.ellipsoids: centre and semi-axes in the
joint frame), else from the URDF: the axis-aligned box, in the joint frame, holding every link's collision
primitives (box, cylinder, sphere; visual ones when a link has no collision element) or, for a link with
only meshes (not read: often not distributed) or no geometry, the joints it carries (its own origin and its
children's) and the uniform-density ellipsoid of its CAD inertial (the solid with the same mass and
inertia); the box is padded by `margin` on every side and the ellipsoid is the one circumscribing it
(semi-axes sqrt(3) x the half-sizes). A body whose CAD mass is zero gets no mass band (a note says so).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.dynamics.inertial import pseudo_inertia
from robocal.dynamics.urdf_inertials import link_parameters
from robocal.errors import InputError

#: the documented band: a body's mass within [1/2, 2] x its CAD mass
MASS_RATIO = (0.5, 2.0)
#: padding (m) around a body's geometry box: joint housings and motor casings a point set of joint origins
#: and a uniform solid miss
MARGIN_M = 0.05
#: below this (kg) a CAD mass counts as zero
ZERO_MASS = 1e-6


@dataclass
class BodyBound:
    """joint: the body's joint; cad_mass (kg); mass_range: (low, high) kg or None (CAD mass zero);
    center, semi_axes (3,): the bounding ellipsoid in the joint frame, axes along the joint frame's;
    source: where the ellipsoid came from (config, collision primitives, joints and CAD inertial)."""

    joint: str
    cad_mass: float
    mass_range: tuple[float, float] | None
    center: np.ndarray
    semi_axes: np.ndarray
    source: str

    def ellipsoid_q(self) -> np.ndarray:
        """Q of the module docstring (4x4): tr(Q pseudo_inertia) >= 0 iff the mass's second moment fits E."""
        A = np.diag(1.0 / np.asarray(self.semi_axes, float) ** 2)
        c = np.asarray(self.center, float)
        Q = np.zeros((4, 4))
        Q[:3, :3] = -A
        Q[:3, 3] = Q[3, :3] = A @ c
        Q[3, 3] = 1.0 - c @ A @ c
        return Q


@dataclass
class LinearBounds:
    """Rows G pi >= h over the inertial parameters (10 per body); labels[i] = (joint, kind), kind one of
    mass_min, mass_max, ellipsoid."""

    G: np.ndarray
    h: np.ndarray
    labels: list[tuple[str, str]]

    def __len__(self) -> int:
        return len(self.h)

    def slack(self, pi: np.ndarray) -> np.ndarray:
        return self.G @ pi - self.h


def linear_bounds(bounds: list[BodyBound], n_bodies: int, body_index: dict[str, int]) -> LinearBounds:
    rows, h, labels = [], [], []
    for b in bounds:
        k = body_index[b.joint]
        if b.mass_range is not None:
            for sign, value, kind in ((1.0, b.mass_range[0], "mass_min"), (-1.0, -b.mass_range[1], "mass_max")):
                row = np.zeros(10 * n_bodies)
                row[10 * k] = sign
                rows.append(row), h.append(value), labels.append((b.joint, kind))
        Q = b.ellipsoid_q()
        row = np.zeros(10 * n_bodies)
        row[10 * k:10 * k + 10] = [np.sum(Q * pseudo_inertia(e)) for e in np.eye(10)]
        rows.append(row), h.append(0.0), labels.append((b.joint, "ellipsoid"))
    G = np.array(rows) if rows else np.zeros((0, 10 * n_bodies))
    return LinearBounds(G, np.array(h, float), labels)


def body_bounds(model: pin.Model, urdf_text: str, mass_ratio=MASS_RATIO, margin: float = MARGIN_M,
                ellipsoids: dict | None = None) -> list[BodyBound]:
    """One BodyBound per moving body of the reduced `model` (module docstring). ellipsoids: {joint:
    {'center': [x, y, z], 'semi_axes': [a, b, c]}} (m, joint frame) overriding the geometry."""
    root = etree.fromstring(urdf_text.encode("utf-8"))
    links = {lk.get("name"): lk for lk in root.findall("link")}
    ellipsoids = ellipsoids or {}
    out = []
    for j in range(1, model.njoints):
        name = model.names[j]
        mass = float(model.inertias[j].mass)
        band = None if mass <= ZERO_MASS else (mass_ratio[0] * mass, mass_ratio[1] * mass)
        if name in ellipsoids:
            e = ellipsoids[name]
            out.append(BodyBound(name, mass, band, np.asarray(e["center"], float), np.asarray(e["semi_axes"], float),
                                 "config"))
            continue
        points, kinds = _body_points(model, j, links)
        lo, hi = points.min(axis=0) - margin, points.max(axis=0) + margin
        out.append(BodyBound(name, mass, band, (lo + hi) / 2, np.sqrt(3.0) * (hi - lo) / 2, " and ".join(sorted(kinds))))
    return out


def _body_points(model: pin.Model, j: int, links: dict) -> tuple[np.ndarray, set[str]]:
    """Points (joint frame) the body's geometry box must hold, and which kinds of geometry gave them."""
    points = [np.zeros(3)]
    points += [model.jointPlacements[c].translation for c in range(1, model.njoints) if model.parents[c] == j]
    kinds = set()
    for frame in model.frames:
        if frame.parentJoint != j:
            continue
        if frame.type != pin.FrameType.BODY:
            points.append(frame.placement.translation)            # a fixed joint's origin on this body
            continue
        link = links.get(frame.name)
        corners = _primitive_corners(link) if link is not None else None
        if corners is None:
            kinds.add("joints and CAD inertials")
            corners = _inertial_box(link) if link is not None else np.zeros((1, 3))
        else:
            kinds.add("collision primitives")
        points += list(frame.placement.act(np.asarray(c, float)) for c in corners)
    return np.array(points), kinds or {"joints"}


def _primitive_corners(link) -> np.ndarray | None:
    """Corners (link frame) of the boxes bounding the link's collision (else visual) primitives; None when
    a geometry is a mesh or the link has none."""
    elements = link.findall("collision") or link.findall("visual")
    if not elements:
        return None
    corners = []
    for el in elements:
        geo = el.find("geometry")
        shape = geo[0] if geo is not None and len(geo) else None
        if shape is None or not isinstance(shape.tag, str):
            return None
        if shape.tag == "box":
            half = np.array([float(x) for x in shape.get("size").split()]) / 2
        elif shape.tag == "cylinder":
            r, length = float(shape.get("radius")), float(shape.get("length"))
            half = np.array([r, r, length / 2])
        elif shape.tag == "sphere":
            half = np.full(3, float(shape.get("radius")))
        else:
            return None
        placement = _origin(el)
        for s in np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T:
            corners.append(placement.act(s * half))
    return np.array(corners)


def _inertial_box(link) -> np.ndarray:
    """Corners (link frame) of the box bounding the uniform solid ellipsoid with the link's CAD mass and
    inertia (semi-axes^2 = 5 (I_j + I_k - I_i) / (2 m); a negative one, an inconsistent inertia, taken as 0)."""
    p = link_parameters(link)
    if p[0] <= ZERO_MASS:
        return np.zeros((1, 3))
    body = pin.Inertia.FromDynamicParameters(p)
    eig, R = np.linalg.eigh(body.inertia)
    axes = np.sqrt(np.maximum(5.0 * (eig.sum() - 2.0 * eig) / (2.0 * body.mass), 0.0))
    half = np.sqrt((R ** 2) @ axes ** 2)
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
    return body.lever + signs * half


def _origin(el) -> pin.SE3:
    origin = el.find("origin")
    xyz = [float(v) for v in ((origin.get("xyz") if origin is not None else None) or "0 0 0").split()]
    rpy = [float(v) for v in ((origin.get("rpy") if origin is not None else None) or "0 0 0").split()]
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))


def check_ellipsoids(value, joints: list[str], source: str) -> dict:
    """model.plausible.ellipsoids from a config: {joint: {center: [3], semi_axes: [3] > 0}}."""
    if not isinstance(value, dict):
        raise InputError("expected {joint: {center: [x, y, z], semi_axes: [a, b, c]}}", source=source,
                         field="model.plausible.ellipsoids")
    out = {}
    for joint, e in value.items():
        field = f"model.plausible.ellipsoids.{joint}"
        if joint not in joints:
            raise InputError(f"'{joint}' is not one of robot.joints", source=source, field=field)
        try:
            center = np.asarray(e["center"], float).reshape(3)
            axes = np.asarray(e["semi_axes"], float).reshape(3)
        except (KeyError, TypeError, ValueError):
            raise InputError("expected center: [x, y, z] and semi_axes: [a, b, c] (m)", source=source,
                             field=field) from None
        if not np.all(np.isfinite(center)) or not np.all(axes > 0):
            raise InputError("center must be finite and semi_axes > 0", source=source, field=field)
        out[joint] = {"center": center.tolist(), "semi_axes": axes.tolist()}
    return out
