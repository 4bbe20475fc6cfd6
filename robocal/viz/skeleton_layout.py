"""The drawn skeleton of a robot: segments and joint spheres, every end given as a point in a link frame.

A segment joins point `pa` of link `a` to point `pb` of link `b`; the viewer places it from the links'
recorded poses at each sample, so a prismatic joint's travel or a strut's length follows the sample.
Points come from the model of one parameter set (before or after calibration), in that link's frame.

  - a link hangs on its parent through its joint: parent origin -> joint origin (on the parent) -> link
    origin (zero for a revolute joint, the travel for a prismatic one);
  - a closed chain's loop anchors: arms from the link origin to each anchor, a sphere at the joint;
  - a plate: a link with three or more loop anchors (a platform), or the root of a closed chain with three
    or more joints on it (a base), is also drawn as the ring through them; the root gets no arms from its
    origin, which is a modelling choice (a Stewart base's origin is far below its joints);
  - a chain with no actuated joint from the root to its leaves that carries a loop anchor (a parallel
    machine's floating platform joint, the PCMM's x-y-z-theta stack) is how the solver places the
    platform, not a body: its joints are not drawn.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin


def _virtual(robot, links: list[dict], joint_of: dict, anchor_links: set) -> set:
    """Links hanging on a 'virtual' joint (see module doc)."""
    if robot.loops is None:
        return set()
    actuated = set(robot.loops.actuated)
    parent = {lk["name"]: lk["parent"] for lk in links}
    children: dict = {}
    for name, p in parent.items():
        children.setdefault(p, []).append(name)

    def below(name):
        out = [name]
        for c in children.get(name, []):
            out += below(c)
        return out

    out = set()
    for lk in links:
        name = lk["name"]
        if parent[name] is None:
            continue
        branch, up = below(name), parent[name]
        sub = set(branch)
        while up is not None:
            branch.append(up)
            up = parent[up]
        if sub & anchor_links and not any(joint_of.get(x) in actuated for x in branch):
            out.add(name)
    return out


def _ring(points: np.ndarray) -> list[int]:
    """Indices of points ordered around their centroid in their best-fit plane."""
    c = points.mean(axis=0)
    _, _, Vt = np.linalg.svd(points - c)
    local = (points - c) @ Vt[:2].T
    return list(np.argsort(np.arctan2(local[:, 1], local[:, 0])))


def skeleton(robot, model: pin.Model, links: list[dict]) -> dict:
    """{"segments": [[a, pa, b, pb, kind]], "spheres": [[link, p, kind]]} for `model` (kinds: link, arm,
    plate; joint, closure)."""
    frames = model.frames
    fid = {lk["name"]: robot.frame_id(lk["name"]) for lk in links}

    def local(link: str, M: pin.SE3) -> list[float]:     # a placement in link's joint frame -> point in link
        return (frames[fid[link]].placement.inverse() * M).translation.tolist()

    joint_of, joint_point = {}, {}
    for lk in links:
        name, p = lk["name"], lk["parent"]
        if p is None:
            continue
        jc, jp = frames[fid[name]].parentJoint, frames[fid[p]].parentJoint
        if jc == jp:                     # fixed joint: the link origin is a point of the parent
            joint_of[name], joint_point[name] = None, local(p, frames[fid[name]].placement)
        else:
            joint_of[name] = model.names[jc]
            # the joint's origin on the parent (a URDF joint hangs on its parent link's joint)
            joint_point[name] = local(p, model.jointPlacements[jc]) if model.parents[jc] == jp else [0.0] * 3
    closures = robot.loops.closures if robot.loops is not None else []
    anchors: dict = {}
    for c in closures:
        for f in (c.frame1, c.frame2):
            link = frames[frames[robot.frame_id(f)].parentFrame].name
            anchors.setdefault(link, []).append((c.name, f, local(link, frames[robot.frame_id(f)].placement)))
    virtual = _virtual(robot, links, joint_of, set(anchors))
    segments, spheres = [], []
    root = links[0]["name"]
    on_root = [lk["name"] for lk in links if lk["parent"] == root and lk["name"] not in virtual]
    root_plate = bool(closures) and len(on_root) >= 3
    for lk in links:
        name, p = lk["name"], lk["parent"]
        if name in virtual or (p is None and root_plate):
            continue
        spheres.append([name, [0.0, 0.0, 0.0], "joint"])
        if p is None:
            continue
        if not (p == root and root_plate):
            segments.append([p, [0.0, 0.0, 0.0], p, joint_point[name], "link"])
        segments.append([p, joint_point[name], name, [0.0, 0.0, 0.0], "link"])
    if root_plate:
        pts = np.array([joint_point[n] for n in on_root])
        order = _ring(pts)
        segments += [[root, pts[i].tolist(), root, pts[j].tolist(), "plate"] for i, j in zip(order, np.roll(order, -1))]
    for link, items in anchors.items():
        for _, _, pt in items:
            segments.append([link, [0.0, 0.0, 0.0], link, pt, "arm"])
        if len(items) >= 3:
            pts = np.array([pt for _, _, pt in items])
            order = _ring(pts)
            segments += [[link, pts[i].tolist(), link, pts[j].tolist(), "plate"]
                         for i, j in zip(order, np.roll(order, -1))]
    for c in closures:   # the joint: on the second anchor's link
        link = frames[frames[robot.frame_id(c.frame2)].parentFrame].name
        spheres.append([link, local(link, frames[robot.frame_id(c.frame2)].placement), "closure"])
    return {"segments": segments, "spheres": spheres}


def skeleton_from_links(scene: dict, state: str) -> dict:
    """A version-1 scene's skeleton (link origins joined, closure arms), from its recorded poses at sample 0."""
    idx = {f: i for i, f in enumerate(scene["frames"])}

    def pose(f):
        x, y, z, qx, qy, qz, qw = scene["poses"][state][0][idx[f]]
        return pin.SE3(pin.Quaternion(qw, qx, qy, qz).toRotationMatrix(), np.array([x, y, z]))

    segments, spheres = [], []
    for lk in scene["robot"]["links"]:
        spheres.append([lk["name"], [0.0, 0.0, 0.0], "joint"])
        if lk["parent"] is not None:
            segments.append([lk["parent"], [0.0, 0.0, 0.0], lk["name"], [0.0, 0.0, 0.0], "link"])
    for c in scene["robot"].get("closures", []):
        for frame, link in zip(c["frames"], c["links"]):
            segments.append([link, [0.0, 0.0, 0.0], link, (pose(link).inverse() * pose(frame)).translation.tolist(), "arm"])
        link = c["links"][1]
        spheres.append([link, (pose(link).inverse() * pose(c["frames"][1])).translation.tolist(), "closure"])
    return {"segments": segments, "spheres": spheres}
