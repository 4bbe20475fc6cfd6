"""Stewart (6-UPS) platforms: geometry, closed-form IK and URDF writer (Newton FK: stewart_fk.py).

Geometry (SI; docs/stewart_calibration.md): base joints N (n_b, 3) in the world/reference frame, platform
joints T (n_p, 3) in the platform frame, and one origin offset o_j per strut, so that for strut j
joining base joint b(j) to platform joint e(j)

    |p + R T_e(j) - N_b(j)| = o_j + s_j          (s_j = strut coordinate read by the NC)

The URDF written by `build_urdf` is a tree (Pinocchio loads it) plus closures (robocal reads them):

    base --floating--> platform --fixed--> tool (tool tip tau in the platform frame)
    base --leg{j}_u1 (rev x)--> leg{j}_cross --leg{j}_u2 (rev y)--> leg{j}_cylinder
         --leg{j}_slide (prismatic z, origin z = o_j)--> leg{j}_rod
    <loop_joint name="leg{j}_top" type="spherical">: rod origin == platform point T_e(j)
    <actuated joints="leg1_slide ... leg6_slide"/>

so the 42 parameters map onto generic kinds: N_j = translation of leg{j}_u1's joint placement;
T_j = translation of frame ``leg{j}_top.link2`` (a loop anchor); o_j = leg{j}_slide's placement z,
which for a prismatic joint along z is the same as that joint's offset (q -> q + delta). The
slide's q is the strut coordinate s_j itself. Joints are numbered from 1 in names.
The 3-3 variant has two legs per base point and per platform point (coinciding joints): in the
URDF each leg keeps its own U joint and anchor at the shared coordinates.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from robocal.errors import InputError
from robocal.systems.stewart.fk import newton_tables
from robocal.io.text_files import format_numbers, write_atomic

@dataclass(frozen=True)
class StewartGeometry:
    """Kinematic parameters of a 6-strut platform (metres).

    base_joints      (n_b, 3) N, base joint centres in the world frame
    platform_joints  (n_p, 3) T, platform joint centres in the platform frame
    legs             (6, 2) int: (base joint index, platform joint index) of each strut
    offsets          (6,) o, joint-to-joint length at strut coordinate 0
    tool             (3,) tool tip tau in the platform frame
    home             (3,) platform origin at the home pose (rotation identity): Newton's default start

    Immutable (arrays read-only): make a new geometry, e.g. with dataclasses.replace, to change it.
    """

    base_joints: np.ndarray
    platform_joints: np.ndarray
    legs: np.ndarray
    offsets: np.ndarray
    tool: np.ndarray = field(default_factory=lambda: np.zeros(3))
    home: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        def frozen(name, shape, dtype=float):
            value = np.array(getattr(self, name), dtype=dtype).reshape(shape)
            value.flags.writeable = False
            object.__setattr__(self, name, value)
            return value

        frozen("base_joints", (-1, 3))
        frozen("platform_joints", (-1, 3))
        legs = frozen("legs", (-1, 2), int)
        frozen("offsets", (-1,))
        frozen("tool", (3,))
        frozen("home", (3,))
        if legs.shape[0] != 6 or self.offsets.size != 6:
            raise InputError("a Stewart platform has 6 struts (legs and offsets)", field="legs")
        if (legs[:, 0].max() >= len(self.base_joints) or legs[:, 1].max() >= len(self.platform_joints)
                or legs.min() < 0):
            raise InputError("leg indices out of range of the joint lists", field="legs")
        for name, points, col in (("leg_base", self.base_joints, 0), ("leg_platform", self.platform_joints, 1)):
            per_leg = points[legs[:, col]]
            per_leg.flags.writeable = False
            object.__setattr__(self, name, per_leg)
        # Unnormalised IK Jacobian, row j = [l_j, T_j x l_j] for the local strut vector l_j:
        # one (36, 18) matrix maps the stacked l (18,) to it.
        big = np.zeros((36, 18))
        for j, t in enumerate(self.platform_joints[legs[:, 1]]):
            big[6 * j:6 * j + 3, 3 * j:3 * j + 3] = np.eye(3)
            big[6 * j + 3:6 * j + 6, 3 * j:3 * j + 3] = [[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]]
        object.__setattr__(self, "_jac_map", big)
        # constant tables of the single-pose FK (stewart_fk.py)
        object.__setattr__(self, "_fk", newton_tables(self.leg_base, self.leg_platform, self.home, big))

    # per-strut copies, leg_base (6, 3) N_b(j) and leg_platform (6, 3) T_e(j), are set in
    # __post_init__ (the code never assumes that joints are distinct per strut)

    @classmethod
    def circular(cls, base_radius, base_angles_deg, base_height, platform_radius, platform_angles_deg,
                 legs, offset, tool=(0.0, 0.0, 0.0), home_height=0.0):
        """Joints on two circles: base at z = base_height, platform at z = 0 of the platform frame."""
        a = np.radians(base_angles_deg)
        b = np.radians(platform_angles_deg)
        base = np.column_stack([base_radius * np.cos(a), base_radius * np.sin(a), np.full(a.size, base_height)])
        plat = np.column_stack([platform_radius * np.cos(b), platform_radius * np.sin(b), np.zeros(b.size)])
        return cls(base, plat, legs, np.full(6, float(offset)), np.asarray(tool, float), (0.0, 0.0, home_height))

    @classmethod
    def spec_6_6(cls) -> "StewartGeometry":
        """The reference machine (docs/stewart_calibration.md): base joints on a 0.7 m circle at z = 1.5 m
        (120k +- 15 deg), platform joints on a 0.25 m circle, o = 0.9 m, tool tip (0, 0, -0.2) m, home tip
        z = 0.35 m."""
        return cls.circular(0.7, [-15, 15, 105, 135, 225, 255], 1.5, 0.25, [-45, 45, 75, 165, 195, 285],
                            [(k, k) for k in range(6)], 0.9, (0.0, 0.0, -0.2), 0.55)

    @classmethod
    def spec_3_3(cls) -> "StewartGeometry":
        """The 3-3 variant (docs/stewart_calibration.md): 3 base points (0.7 m circle), 3 platform points
        (0.25 m circle, interleaved by 60 deg), struts (B1,P1) (B1,P2) (B2,P2) (B2,P3) (B3,P3) (B3,P1)."""
        legs = [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2), (2, 0)]
        return cls.circular(0.7, [0, 120, 240], 1.5, 0.25, [-60, 60, 180], legs, 0.9, (0.0, 0.0, -0.2), 0.55)

    @property
    def home_pose(self) -> pin.SE3:
        return pin.SE3(np.eye(3), self.home.copy())


# ---- poses ----------------------------------------------------------------------------------
def rotation_xyz(abc) -> np.ndarray:
    """R = Rx(A) Ry(B) Rz(C) (docs/stewart_calibration.md) from angles (3,) in rad, or a batch (K, 3) -> (K, 3, 3)."""
    abc = np.asarray(abc, dtype=float)
    a, b, c = np.moveaxis(np.atleast_2d(abc), -1, 0)
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    R = np.stack([
        np.stack([cb * cc, -cb * sc, sb], -1),
        np.stack([sa * sb * cc + ca * sc, -sa * sb * sc + ca * cc, -sa * cb], -1),
        np.stack([-ca * sb * cc + sa * sc, ca * sb * sc + sa * cc, ca * cb], -1)], -2)
    return R[0] if abc.ndim == 1 else R


def random_workspace_poses(geometry: StewartGeometry, n: int, rng: np.random.Generator,
                           xy=0.15, z=(0.25, 0.45), angle_deg=15.0):
    """Random platform poses whose tool tip lies in the reference workspace (docs/stewart_calibration.md):
    tip x, y in +-xy, z in `z`, angles A, B, C in +-angle_deg. Returns R (n, 3, 3) and platform origins p (n, 3)."""
    tip = np.column_stack([rng.uniform(-xy, xy, n), rng.uniform(-xy, xy, n), rng.uniform(z[0], z[1], n)])
    R = rotation_xyz(np.radians(rng.uniform(-angle_deg, angle_deg, (n, 3))))
    return R, tip - R @ geometry.tool


# ---- closed-form inverse kinematics ----------------------------------------------------------
# Everything is written with the local strut vector l_j = R^T (p - N_j) + T_j (platform frame):
# |l_j| = o_j + s_j, and for a LOCAL twist xi = [v; w] of the platform (M <- M exp6(xi))
# d|l_j| = (l_j / |l_j|) . (v + w x T_j), i.e. row j of ds/dxi = [l_j, T_j x l_j] / |l_j|.

def local_strut_vectors(geometry: StewartGeometry, R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """l (K, 6, 3) in the platform frame for poses R (K, 3, 3), p (K, 3)."""
    return (p[:, None, :] - geometry.leg_base) @ R + geometry.leg_platform


def inverse_kinematics_batch(geometry: StewartGeometry, R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Strut coordinates s (K, 6) = |p + R T - N| - o for platform poses R (K, 3, 3), p (K, 3)."""
    d = local_strut_vectors(geometry, R, p)
    return np.sqrt(np.einsum("kji,kji->kj", d, d)) - geometry.offsets


def inverse_kinematics(geometry: StewartGeometry, pose: pin.SE3) -> np.ndarray:
    """Strut coordinates s (6,) (m) of one platform pose (world SE3 of the platform frame)."""
    d = (pose.translation - geometry.leg_base) @ pose.rotation + geometry.leg_platform
    return np.sqrt((d * d).sum(1)) - geometry.offsets


def ik_jacobian(geometry: StewartGeometry, pose: pin.SE3) -> np.ndarray:
    """(6, 6) derivative of the strut coordinates w.r.t. a LOCAL right twist [v; w] of the platform."""
    d = (pose.translation - geometry.leg_base) @ pose.rotation + geometry.leg_platform
    return (geometry._jac_map @ d.ravel()).reshape(6, 6) / np.sqrt((d * d).sum(1))[:, None]


# ---- URDF ------------------------------------------------------------------------------------
def aim_z(direction: np.ndarray) -> np.ndarray:
    """A rotation whose z axis is `direction` (the U joint's home frame)."""
    z = direction / np.linalg.norm(direction)
    x = np.cross(np.eye(3)[int(np.argmin(np.abs(z)))], z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def build_urdf(geometry: StewartGeometry, name: str = "stewart") -> str:
    """URDF text (spanning tree + <loop_joint> closures + <actuated>) of a Stewart platform."""
    N, T, o = geometry.leg_base, geometry.leg_platform, geometry.offsets
    home_tips = geometry.home + T
    out = ['<?xml version="1.0"?>',
           f'<robot name="{name}">',
           "  <!-- Written by robocal.systems.stewart.mechanism.build_urdf. Units: m, rad.",
           "       N_j = origin xyz of leg{j}_u1; T_j = link2 xyz of loop_joint leg{j}_top (platform frame);",
           "       o_j = origin z of leg{j}_slide, whose position is the strut coordinate s_j. -->",
           '  <link name="base"/>', '  <link name="platform"/>', '  <link name="tool"/>',
           '  <joint name="platform_float" type="floating">',
           f'    <parent link="base"/><child link="platform"/><origin xyz="{format_numbers(geometry.home)}" rpy="0 0 0"/>',
           "  </joint>",
           '  <joint name="tool_mount" type="fixed">',
           f'    <parent link="platform"/><child link="tool"/><origin xyz="{format_numbers(geometry.tool)}" rpy="0 0 0"/>',
           "  </joint>"]
    limit = '<limit lower="-1.5707963267948966" upper="1.5707963267948966" effort="0" velocity="0"/>'
    for j in range(6):
        leg = f"leg{j + 1}"
        rpy = pin.rpy.matrixToRpy(aim_z(home_tips[j] - N[j]))
        out += [f'  <link name="{leg}_cross"/>', f'  <link name="{leg}_cylinder"/>', f'  <link name="{leg}_rod"/>',
                f'  <joint name="{leg}_u1" type="revolute">',
                f'    <parent link="base"/><child link="{leg}_cross"/>',
                f'    <origin xyz="{format_numbers(N[j])}" rpy="{format_numbers(rpy)}"/><axis xyz="1 0 0"/>{limit}',
                "  </joint>",
                f'  <joint name="{leg}_u2" type="revolute">',
                f'    <parent link="{leg}_cross"/><child link="{leg}_cylinder"/>',
                f'    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>{limit}',
                "  </joint>",
                f'  <joint name="{leg}_slide" type="prismatic">',
                f'    <parent link="{leg}_cylinder"/><child link="{leg}_rod"/>',
                f'    <origin xyz="0 0 {format_numbers(o[j])}" rpy="0 0 0"/><axis xyz="0 0 1"/>',
                f'    <limit lower="{format_numbers(-o[j])}" upper="{format_numbers(o[j])}" effort="0" velocity="0"/>',
                "  </joint>",
                f'  <loop_joint name="{leg}_top" type="spherical">',
                f'    <link1 link="{leg}_rod" xyz="0 0 0" rpy="0 0 0"/>',
                f'    <link2 link="platform" xyz="{format_numbers(T[j])}" rpy="0 0 0"/>',
                "  </loop_joint>"]
    out += [f'  <actuated joints="{" ".join(f"leg{j + 1}_slide" for j in range(6))}"/>', "</robot>", ""]
    return "\n".join(out)


def write_urdf(geometry: StewartGeometry, path: str | Path, name: str = "stewart") -> Path:
    return write_atomic(path, build_urdf(geometry, name))


def geometry_from_model(robot, model: pin.Model | None = None, tol: float = 1e-12) -> StewartGeometry:
    """Read N, T, o (and tool, home) back from a model of a URDF written by `build_urdf`.

    `model` may be a calibrated copy of robot.model with edited N (u1 placement translation),
    T (leg{j}_top.link2 frame translation) and o (slide placement z). Raises InputError if other
    placements were edited so that the closed form no longer describes the model.
    """
    model = robot.model if model is None else model
    bad = []

    def jid(name):
        return robot.joint_id(name)

    base, plat, o = np.zeros((6, 3)), np.zeros((6, 3)), np.zeros(6)
    fj = jid("platform_float")
    for j in range(6):
        leg = f"leg{j + 1}"
        u1, u2, slide = jid(f"{leg}_u1"), jid(f"{leg}_u2"), jid(f"{leg}_slide")
        base[j] = model.jointPlacements[u1].translation
        if model.parents[u1] != 0 or np.linalg.norm(model.jointPlacements[u2].translation) > tol:
            bad.append(f"{leg}_u2")
        ms = model.jointPlacements[slide]
        if np.linalg.norm(ms.translation[:2]) > tol or np.linalg.norm(ms.rotation - np.eye(3)) > tol:
            bad.append(f"{leg}_slide")
        o[j] = ms.translation[2]
        f1 = model.frames[robot.frame_id(f"{leg}_top.link1")]
        f2 = model.frames[robot.frame_id(f"{leg}_top.link2")]
        if f1.parentJoint != slide or np.linalg.norm(f1.placement.translation) > tol:
            bad.append(f"{leg}_top.link1")
        if f2.parentJoint != fj:
            bad.append(f"{leg}_top.link2")
        plat[j] = f2.placement.translation
    if bad:
        raise InputError(f"the model is not a closed-form Stewart platform: {', '.join(bad)} moved in ways "
                         "N, T, o cannot describe; use robocal.model.loops.assemble", field=bad[0])
    tool = model.frames[robot.frame_id("tool")].placement.translation
    return StewartGeometry(base, plat, [(k, k) for k in range(6)], o, tool.copy(),
                           model.jointPlacements[fj].translation.copy())


def platform_pose(robot, model: pin.Model, q: np.ndarray, data: pin.Data | None = None) -> pin.SE3:
    """World pose of the platform frame in configuration q (nq,) of a `build_urdf` model."""
    data = model.createData() if data is None else data
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[robot.frame_id("platform")].copy()


def configuration_from_pose(robot, geometry: StewartGeometry, pose: pin.SE3,
                            model: pin.Model | None = None) -> np.ndarray:
    """Full q (nq,) of a `build_urdf` model at a platform pose, from the closed form (U angles by
    geometry, slides by IK): an exact assembly, useful as a warm start or as test truth."""
    model = robot.model if model is None else model
    q = pin.neutral(model)
    fj = model.joints[robot.joint_id("platform_float")]
    q[fj.idx_q:fj.idx_q + 7] = pin.SE3ToXYZQUAT(model.jointPlacements[robot.joint_id("platform_float")].actInv(pose))
    s = inverse_kinematics(geometry, pose)
    tips = pose.translation + geometry.leg_platform @ pose.rotation.T
    for j in range(6):
        leg = f"leg{j + 1}"
        u1 = robot.joint_id(f"{leg}_u1")
        local = model.jointPlacements[u1].rotation.T @ (tips[j] - geometry.leg_base[j])
        # leg direction in the u1 frame: Rx(a) Ry(b) e_z = (sin b, -sin a cos b, cos a cos b)
        a = np.arctan2(-local[1], local[2])
        b = np.arctan2(local[0], np.hypot(local[1], local[2]))
        q[model.joints[u1].idx_q] = a
        q[model.joints[robot.joint_id(f"{leg}_u2")].idx_q] = b
        q[model.joints[robot.joint_id(f"{leg}_slide")].idx_q] = s[j]
    return q
