"""ISO 9283 pose and distance characteristics from repeated visits of commanded poses.

A pose is six numbers (x, y, z, a, b, c): a position (m) and orientation angles (rad) about x, y, z,
with R = Rz(c) Ry(b) Rx(a) (URDF roll-pitch-yaw, `pin.rpy`). For a commanded pose c visited n times
(attained poses j = 1..n), the standard defines (ISO 9283:1998, 7.2 and 7.3):

  pose accuracy      x_bar = mean x_j ...;  AP_x = x_bar - x_c (y, z alike)
                     AP_P = sqrt(AP_x^2 + AP_y^2 + AP_z^2)
                     AP_a = a_bar - a_c, AP_b = b_bar - b_c, AP_c = c_bar - c_c
  pose repeatability l_j = |p_j - p_bar|, l_bar = mean l_j, S_l = sqrt(sum (l_j - l_bar)^2 / (n - 1))
                     RP_l = l_bar + 3 S_l;  RP_a = +-3 S_a with S_a the (n - 1) standard deviation of a_j
                     (b, c alike; the +- is implied: the figures hold the half width 3 S)

and for two commanded poses 1 and 2 visited in the same cycles j (ISO 9283, 7.5):

  distance accuracy       D_j = |p_1j - p_2j|, D_c = |p_c1 - p_c2|, AD_P = mean D_j - D_c
                          AD_x = mean(x_1j - x_2j) - (x_c1 - x_c2) (y, z, a, b, c alike)
  distance repeatability  RD_P = 3 S_D; RD_x = 3 S_Dx ... (n - 1 standard deviations)

Angles are averaged as their differences from the commanded angle, wrapped to (-pi, pi]: the same
numbers as the standard's a_bar - a_c whenever the visits do not straddle +-pi, and the right ones
when they do. All inputs and outputs are SI (m, rad); `summary()` shows mm and mrad and says so.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robocal.errors import InputError

AXES = ("x", "y", "z")
ANGLES = ("a", "b", "c")


def wrap(angle):
    """Angles wrapped to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2 * np.pi)


def pose6(M: pin.SE3) -> np.ndarray:
    """(x, y, z, a, b, c) of an SE3, angles as URDF roll-pitch-yaw."""
    return np.concatenate([M.translation, pin.rpy.matrixToRpy(M.rotation)])


def _std(v: np.ndarray, axis=0) -> np.ndarray:
    """Sample standard deviation (n - 1), the standard's S."""
    return np.std(v, axis=axis, ddof=1)


@dataclass
class PoseFigures:
    """Accuracy and repeatability of one commanded pose (SI: m, rad)."""

    pose_id: str
    n: int
    commanded: np.ndarray     # (6,) x y z a b c
    barycentre: np.ndarray    # (6,) x_bar .. c_bar (angles: commanded + mean wrapped difference)
    AP: float                 # AP_P
    AP_xyz: np.ndarray        # (3,) AP_x AP_y AP_z
    AP_abc: np.ndarray        # (3,) AP_a AP_b AP_c
    l_bar: float
    S_l: float
    RP: float                 # RP_l = l_bar + 3 S_l
    RP_abc: np.ndarray        # (3,) 3 S_a, 3 S_b, 3 S_c

    def to_dict(self) -> dict:
        return {"pose": self.pose_id, "visits": self.n, "commanded": self.commanded.tolist(),
                "barycentre": self.barycentre.tolist(), "AP": self.AP,
                **{f"AP_{k}": float(v) for k, v in zip(AXES + ANGLES, np.r_[self.AP_xyz, self.AP_abc])},
                "l_bar": self.l_bar, "S_l": self.S_l, "RP": self.RP,
                **{f"RP_{k}": float(v) for k, v in zip(ANGLES, self.RP_abc)}}


@dataclass
class DistanceFigures:
    """Distance accuracy and repeatability between two commanded poses (SI)."""

    pose_ids: tuple[str, str]
    n: int
    D_c: float
    D_bar: float
    AD: float                 # AD_P = D_bar - D_c
    AD_xyzabc: np.ndarray     # (6,) AD_x .. AD_c
    RD: float                 # 3 S_D
    RD_xyzabc: np.ndarray     # (6,) 3 S_Dx .. 3 S_Dc

    def to_dict(self) -> dict:
        keys = AXES + ANGLES
        return {"poses": list(self.pose_ids), "cycles": self.n, "D_c": self.D_c, "D_bar": self.D_bar,
                "AD": self.AD, **{f"AD_{k}": float(v) for k, v in zip(keys, self.AD_xyzabc)},
                "RD": self.RD, **{f"RD_{k}": float(v) for k, v in zip(keys, self.RD_xyzabc)}}


def pose_characteristics(commanded, attained, pose_id: str = "") -> PoseFigures:
    """AP and RP of one commanded pose (6,) from its attained poses (n, 6), n >= 2."""
    c = np.asarray(commanded, dtype=float).reshape(6)
    att = np.asarray(attained, dtype=float).reshape(-1, 6)
    n = len(att)
    if n < 2:
        raise InputError(f"pose '{pose_id}' is visited {n} time(s); repeatability needs at least 2 visits",
                         field=str(pose_id) or None)
    p = att[:, :3]
    p_bar = p.mean(axis=0)
    d_ang = wrap(att[:, 3:] - c[3:])          # a_j - a_c, wrapped
    ap_xyz = p_bar - c[:3]
    ap_abc = d_ang.mean(axis=0)
    l = np.linalg.norm(p - p_bar, axis=1)
    l_bar, s_l = float(l.mean()), float(_std(l))
    return PoseFigures(str(pose_id), n, c, np.r_[p_bar, c[3:] + ap_abc], float(np.linalg.norm(ap_xyz)), ap_xyz,
                       ap_abc, l_bar, s_l, l_bar + 3 * s_l, 3 * _std(d_ang))


def distance_characteristics(commanded1, commanded2, attained1, attained2,
                             pose_ids: tuple[str, str] = ("1", "2")) -> DistanceFigures:
    """AD and RD between two commanded poses; attained1[j] and attained2[j] belong to cycle j."""
    c1, c2 = (np.asarray(c, dtype=float).reshape(6) for c in (commanded1, commanded2))
    a1, a2 = (np.asarray(a, dtype=float).reshape(-1, 6) for a in (attained1, attained2))
    if len(a1) != len(a2) or len(a1) < 2:
        raise InputError(f"distance {pose_ids[0]}-{pose_ids[1]} needs the same number (>= 2) of visits of "
                         f"both poses, got {len(a1)} and {len(a2)}", field="distance_pairs")
    dc = np.r_[c1[:3] - c2[:3], wrap(c1[3:] - c2[3:])]
    # angle differences taken relative to the commanded difference, so wrapping never splits a cluster
    dj = np.hstack([a1[:, :3] - a2[:, :3], dc[3:] + wrap(a1[:, 3:] - a2[:, 3:] - dc[3:])])
    D = np.linalg.norm(dj[:, :3], axis=1)
    D_c = float(np.linalg.norm(dc[:3]))
    return DistanceFigures((str(pose_ids[0]), str(pose_ids[1])), len(a1), D_c, float(D.mean()),
                           float(D.mean()) - D_c, dj.mean(axis=0) - dc, 3 * float(_std(D)), 3 * _std(dj))


@dataclass
class Iso9283Figures:
    """Figures of every commanded pose and of the chosen pose pairs, for one model ("nominal", ...)."""

    label: str
    poses: list[PoseFigures]
    distances: list[DistanceFigures] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def worst_AP(self) -> float:
        return max(p.AP for p in self.poses)

    @property
    def worst_RP(self) -> float:
        return max(p.RP for p in self.poses)

    def to_dict(self) -> dict:
        return {"model": self.label, "units": "SI (m, rad)", "poses": [p.to_dict() for p in self.poses],
                "distances": [d.to_dict() for d in self.distances], "notes": list(self.notes)}


def group_visits(pose_ids) -> dict[str, np.ndarray]:
    """{pose id: row indices}, pose ids in order of first appearance (a deterministic order)."""
    ids = [str(p) for p in pose_ids]
    groups: dict[str, list[int]] = {}
    for i, p in enumerate(ids):
        groups.setdefault(p, []).append(i)
    return {k: np.array(v, dtype=int) for k, v in groups.items()}


def iso9283_figures(pose_ids, commanded, attained, distance_pairs=None, label: str = "") -> Iso9283Figures:
    """All figures from per-row data.

    pose_ids        (N,) commanded-pose label of each row
    commanded       (N, 6) commanded pose of each row (constant within a pose id)
    attained        (N, 6) attained pose of each row
    distance_pairs  [(id1, id2)]; None: consecutive pose ids in order of appearance. The k-th visit of
                    id1 is paired with the k-th visit of id2 (one cycle); pairs whose visit counts
                    differ are skipped with a note.
    """
    commanded = np.asarray(commanded, dtype=float).reshape(-1, 6)
    attained = np.asarray(attained, dtype=float).reshape(-1, 6)
    groups = group_visits(pose_ids)
    if len(commanded) != len(attained) or len(attained) != sum(len(v) for v in groups.values()):
        raise InputError("pose ids, commanded and attained poses need one row each per visit")
    notes = []
    cmd = {}
    for pid, rows in groups.items():
        spread = np.abs(commanded[rows] - commanded[rows[0]])
        spread[:, 3:] = np.abs(wrap(spread[:, 3:]))
        if spread.max() > 1e-9:
            raise InputError(f"pose '{pid}' has different commanded poses on different rows", field=pid)
        cmd[pid] = commanded[rows[0]]
    poses = [pose_characteristics(cmd[pid], attained[rows], pid) for pid, rows in groups.items()]
    keys = list(groups)
    pairs = list(zip(keys[:-1], keys[1:])) if distance_pairs is None else [tuple(p) for p in distance_pairs]
    distances = []
    for p1, p2 in pairs:
        for p in (p1, p2):
            if str(p) not in groups:
                raise InputError(f"distance pair names pose '{p}', which the data do not have "
                                 f"(poses: {', '.join(keys)})", field="distance_pairs")
        r1, r2 = groups[str(p1)], groups[str(p2)]
        if len(r1) != len(r2):
            notes.append(f"distance {p1}-{p2} skipped: {len(r1)} and {len(r2)} visits cannot be paired "
                         "into cycles")
            continue
        distances.append(distance_characteristics(cmd[str(p1)], cmd[str(p2)], attained[r1], attained[r2],
                                                  (str(p1), str(p2))))
    return Iso9283Figures(label, poses, distances, notes)


def model_attained(nominal_at_command: list[pin.SE3], model_at_command: list[pin.SE3],
                   measured: list[pin.SE3]) -> list[pin.SE3]:
    """Attained poses predicted for the same robot driven through another model M.

    The robot ran with its nominal model N: commanded to P_c, it went to joints q_c with N(q_c) = P_c
    and visit j measured y_j ~ true(q_c). Driven through M it would go to q' with M(q') = P_c and land
    at true(q') = P_c E(q'), where E = M^-1 true is M's remaining error; to first order in how E varies
    between q_c and q', that is N(q_c) M(q_c)^-1 y_j. For M = N this is the measured pose itself; for
    any M it moves every visit of a pose by one rigid transform, so repeatability stays as measured and
    only accuracy changes, as calibration does on a real robot. Both models are evaluated at the same
    q_c, so an estimate of q_c (the mean reading of the visits) costs only second-order errors.
    """
    return [N * M.inverse() * y for N, M, y in zip(nominal_at_command, model_at_command, measured)]


def summary(figures: list[Iso9283Figures]) -> str:
    """Text table of one or more models' figures side by side (mm and mrad)."""
    labels = [f.label or f"model {i}" for i, f in enumerate(figures)]
    w = 14
    head = f"{'pose':<10}{'figure':<8}" + "".join(f"{lab:>{w}}" for lab in labels)
    lines = ["ISO 9283 pose characteristics (positions in mm, angles in mrad)", head]
    rows = [("AP", lambda p: p.AP * 1e3), ("AP_x", lambda p: p.AP_xyz[0] * 1e3),
            ("AP_y", lambda p: p.AP_xyz[1] * 1e3), ("AP_z", lambda p: p.AP_xyz[2] * 1e3),
            ("AP_a", lambda p: p.AP_abc[0] * 1e3), ("AP_b", lambda p: p.AP_abc[1] * 1e3),
            ("AP_c", lambda p: p.AP_abc[2] * 1e3), ("RP", lambda p: p.RP * 1e3),
            ("RP_a", lambda p: p.RP_abc[0] * 1e3), ("RP_b", lambda p: p.RP_abc[1] * 1e3),
            ("RP_c", lambda p: p.RP_abc[2] * 1e3)]
    for k, pose in enumerate(figures[0].poses):
        for name, get in rows:
            vals = "".join(f"{get(f.poses[k]):>{w}.4f}" for f in figures)
            lines.append(f"{pose.pose_id:<10}{name:<8}{vals}")
    if figures[0].distances:
        lines += ["", "ISO 9283 distance characteristics (mm, mrad)", head.replace("pose      ", "pair      ")]
        for k, d in enumerate(figures[0].distances):
            pair = f"{d.pose_ids[0]}-{d.pose_ids[1]}"
            for name, get in (("AD", lambda d: d.AD * 1e3), ("RD", lambda d: d.RD * 1e3)):
                vals = "".join(f"{get(f.distances[k]):>{w}.4f}" for f in figures)
                lines.append(f"{pair:<10}{name:<8}{vals}")
    for f, lab in zip(figures, labels):
        lines += [f"note ({lab}): {n}" for n in f.notes]
    return "\n".join(lines)
