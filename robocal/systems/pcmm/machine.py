"""The 4-PUU parallel CMM (docs/pcmm_calibration.md): reference design, URDF writer, artefact and probing plan.

URDF written by `build_urdf` (a tree Pinocchio loads, plus closures robocal reads; units m, rad):

    base --platform_x/_y/_z (prismatic, origin z = home height)--> --platform_rz (revolute z)--> platform
    platform --probe_mount (fixed, origin = stylus t)--> probe_tip
    base --limb{i}_slide (prismatic along e_i; origin xyz = A_i, rpy = Rx(alpha_i) Ry(beta_i))--> limb{i}_slider
         --limb{i}_u1 (revolute x, origin rpy = pi 0 0: rod z axis points down)--> limb{i}_cross
         --limb{i}_u2 (revolute y)--> limb{i}_rod
    <loop_joint name="limb{i}_top" type="spherical">: rod point (0, 0, l_i) == platform point b_i
    <actuated joints="limb1_slide ... limb4_slide"/>

Mapping of the 32 reduced parameters onto robocal's generic kinds (see `generic_parameters`):

    limb{i}.ax, .ay     joint placement limb{i}_slide.tx, .ty   (the origin's frame is world-aligned)
    limb{i}.alpha, .beta   joint placement limb{i}_slide.rx, .ry  (exp(rx x + ry y) z = Rx Ry z to 1st order)
    limb{i}.bx, .by, .bz   frame placement limb{i}_top.link2.tx, .ty, .tz   (loop anchor on the platform)
    limb{i}.l           frame placement limb{i}_top.link1.tz   (loop anchor on the rod, rod z along the link)

The raw slider zero offset p0_i is the generic joint offset limb{i}_slide.offset; in the reduced model
it is merged into b_z (the reduction of robocal.systems.pcmm.error_model), so the 32-parameter set leaves it fixed.
The second Hooke joint is modelled as a spherical closure (positions are all the 3T1R model needs).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.errors import InputError
from robocal.io.text_files import format_numbers, write_atomic
from robocal.model.loops_urdf import read_loops
from robocal.model.parameters import Parameter, ParameterSet
from robocal.model.robot import Robot
from robocal.systems.pcmm.error_model import RawPCMM, raw_inverse_kinematics
from robocal.systems.pcmm.kinematics import LIMB_FIELDS, PCMMGeometry, axis_directions, inverse_kinematics, rz

PHI = np.radians([45.0, 135.0, 225.0, 315.0])
HOME_Z = -0.65

# reduced field -> (generic kind, target pattern, component)
GENERIC_MAP = {
    "ax": ("joint_placement", "limb{i}_slide", "tx"), "ay": ("joint_placement", "limb{i}_slide", "ty"),
    "beta": ("joint_placement", "limb{i}_slide", "ry"), "alpha": ("joint_placement", "limb{i}_slide", "rx"),
    "bx": ("frame_placement", "limb{i}_top.link2", "tx"), "by": ("frame_placement", "limb{i}_top.link2", "ty"),
    "bz": ("frame_placement", "limb{i}_top.link2", "tz"), "l": ("frame_placement", "limb{i}_top.link1", "tz"),
}
_INDEX = {"tx": 0, "ty": 1, "tz": 2, "rx": 3, "ry": 4, "rz": 5}


def reference_raw() -> RawPCMM:
    """The reference design (docs/pcmm_calibration.md) with its raw parts: a = 350 mm radius, d = -40 mm,
    b = 90 mm (+-35 deg)."""
    c, s = np.cos(PHI), np.sin(PHI)
    a = 0.35 * np.column_stack([c, s, np.zeros(4)])
    d = -0.04 * np.column_stack([c, s, np.zeros(4)])
    ang = PHI + np.radians(35.0) * np.array([1, -1, 1, -1])
    b = 0.09 * np.column_stack([np.cos(ang), np.sin(ang), np.zeros(4)])
    return RawPCMM(a, np.zeros((4, 2)), np.zeros(4), d, np.full(4, 0.6), b, np.array([0.015, 0.0, -0.12]),
                   1e-3, np.array([0.0, 0.0, HOME_Z, 0.0]))


def reference_geometry() -> PCMMGeometry:
    """The nominal reduced machine of the reference design (A_i = a_i + d_i)."""
    r = reference_raw()
    return PCMMGeometry(r.a + r.d, r.tilts, r.b, r.lengths, r.stylus, r.tip_radius, r.home)


@dataclass(frozen=True)
class Artefact:
    """A calibrated multi-sphere artefact: local centres (S, 3), reference radii (S,), distances (S, S)."""

    centres: np.ndarray
    radii: np.ndarray
    distances: np.ndarray

    @classmethod
    def from_centres(cls, centres, radii) -> "Artefact":
        c = np.asarray(centres, dtype=float).reshape(-1, 3)
        c = c - c.mean(axis=0)
        r = np.broadcast_to(np.asarray(radii, dtype=float), (len(c),)).copy()
        if len(c) < 2:
            raise InputError("an artefact needs at least 2 spheres", field="centres")
        return cls(c, r, np.linalg.norm(c[:, None] - c[None], axis=2))

    @property
    def n_spheres(self) -> int:
        return len(self.centres)


def reference_artefact() -> Artefact:
    """The reference artefact: four 12.7 mm spheres (distances 200.998, 250.000, 155.242, ... mm)."""
    return Artefact.from_centres(np.array([[0, 0, 0], [200, 0, 20], [200, 150, 0], [0, 150, 40]]) * 1e-3, 0.0127)


def reference_placements() -> tuple[np.ndarray, np.ndarray]:
    """The reference run's 8 artefact centroids (8, 3) and yaws (8,)."""
    off = np.array([[0, 0, 0], [60, 40, -40], [-50, 60, 30], [40, -60, -60], [-60, -40, 20], [0, 0, -80],
                    [30, 30, 40], [-30, 20, -20]]) * 1e-3
    return off + np.array([0.0, 0.0, HOME_Z]), np.array([0.0, 0.5, 1.2, 2.0, 2.8, 0.9, -0.7, -1.8])


@dataclass
class ProbeHits:
    """Touch-probe triggers: readings (N, 4) m, placement (N,) and sphere (N,) indices, theta_cmd (N,)
    (the commanded rotation, FK's start). `excluded`: (placement, sphere) pairs left out (flagged)."""

    readings: np.ndarray
    placement: np.ndarray
    sphere: np.ndarray
    theta_cmd: np.ndarray
    excluded: frozenset = frozenset()

    def groups(self) -> list[list[np.ndarray]]:
        """Hit indices per placement, per sphere."""
        return [[np.flatnonzero((self.placement == g) & (self.sphere == j)) for j in np.unique(self.sphere)]
                for g in np.unique(self.placement)]


def cap_directions(n: int, max_polar: float = np.radians(75.0)) -> np.ndarray:
    """(n, 3) unit outward normals on a golden-spiral cap around +z, the pole first."""
    k = np.arange(n)
    cos_p = 1.0 - (1.0 - np.cos(max_polar)) * k / max(n - 1, 1)
    sin_p = np.sqrt(1.0 - cos_p ** 2)
    az = k * np.pi * (3.0 - np.sqrt(5.0))
    return np.column_stack([sin_p * np.cos(az), sin_p * np.sin(az), cos_p])


def simulate_probing(true_machine, artefact: Artefact, centroids, yaws, rng: np.random.Generator,
                     n_hits: int = 9, theta_range: float = 0.3, noise: float = 0.0, pretravel=None) -> ProbeHits:
    """Hits of the true machine on every sphere of every placement (docs/pcmm_calibration.md).

    true_machine: PCMMGeometry or RawPCMM (RawPCMM uses the raw model), or anything with a method
    `readings(Y)` and `tip_radius`, `stylus` (robocal.systems.pcmm.realism.BowedColumns). `artefact`: the
    true artefact. Tip centres lie on the sphere of radius r_ref + r_tip, less the probe's pre-travel
    `pretravel(normals in the probe frame)` (m, or None); theta is uniform in +-theta_range per hit;
    `noise` is the standard deviation (m) of independent Gaussian axis-reading noise.
    """
    if hasattr(true_machine, "readings"):
        ik = type(true_machine).readings
    else:
        ik = raw_inverse_kinematics if isinstance(true_machine, RawPCMM) else inverse_kinematics
    dirs = cap_directions(n_hits)
    rows, plc, sph = [], [], []
    thetas = []
    for g, (C, yaw) in enumerate(zip(np.asarray(centroids).reshape(-1, 3), np.asarray(yaws).reshape(-1))):
        centres = C + artefact.centres @ rz(yaw).T
        for j, c in enumerate(centres):
            th = rng.uniform(-theta_range, theta_range, n_hits) if theta_range > 0 else np.zeros(n_hits)
            short = 0.0 if pretravel is None else pretravel(np.einsum("nba,nb->na", rz(th), dirs))[:, None]
            X = c + (artefact.radii[j] + true_machine.tip_radius - short) * dirs
            q = X - np.einsum("nab,b->na", rz(th), true_machine.stylus)
            rows.append(ik(true_machine, np.column_stack([q, th])))
            plc += [g] * n_hits
            sph += [j] * n_hits
            thetas.append(th)
    readings = np.vstack(rows)
    if noise > 0:
        readings = readings + rng.normal(0.0, noise, readings.shape)
    return ProbeHits(readings, np.array(plc), np.array(sph), np.concatenate(thetas))


# ---- URDF and generic parameters ------------------------------------------------------------
def build_urdf(geo: PCMMGeometry, name: str = "pcmm_4puu") -> str:
    """URDF text (spanning tree + <loop_joint> closures + <actuated>) of the reduced machine `geo`."""
    lim = '<limit lower="-1.5707963267948966" upper="1.5707963267948966" effort="0" velocity="0"/>'
    slide_lim = '<limit lower="-1" upper="1" effort="0" velocity="0"/>'
    out = ['<?xml version="1.0"?>', f'<robot name="{name}">',
           "  <!-- Written by robocal.systems.pcmm.machine.build_urdf (docs/pcmm_calibration.md). Units: m, rad.",
           "       A_i = origin xyz of limb{i}_slide, tilts = its rpy (Rx(alpha) Ry(beta)); b_i = link2 xyz of",
           "       loop_joint limb{i}_top (moving frame); l_i = link1 z of it. Platform origin z is offset by",
           f"       {format_numbers(geo.home[2])} m (the home height). -->",
           '  <link name="base"/>', '  <link name="platform_xl"/>', '  <link name="platform_yl"/>',
           '  <link name="platform_zl"/>', '  <link name="platform"/>', '  <link name="probe_tip"/>']
    for joint, axis, parent, child, xyz in (
            ("platform_x", "1 0 0", "base", "platform_xl", f"0 0 {format_numbers(geo.home[2])}"),
            ("platform_y", "0 1 0", "platform_xl", "platform_yl", "0 0 0"),
            ("platform_z", "0 0 1", "platform_yl", "platform_zl", "0 0 0")):
        out += [f'  <joint name="{joint}" type="prismatic">',
                f'    <parent link="{parent}"/><child link="{child}"/><origin xyz="{xyz}" rpy="0 0 0"/>'
                f'<axis xyz="{axis}"/>{slide_lim}', "  </joint>"]
    out += ['  <joint name="platform_rz" type="revolute">',
            '    <parent link="platform_zl"/><child link="platform"/><origin xyz="0 0 0" rpy="0 0 0"/>'
            '<axis xyz="0 0 1"/><limit lower="-3.2" upper="3.2" effort="0" velocity="0"/>', "  </joint>",
            '  <joint name="probe_mount" type="fixed">',
            f'    <parent link="platform"/><child link="probe_tip"/><origin xyz="{format_numbers(geo.stylus)}" rpy="0 0 0"/>',
            "  </joint>"]
    for i in range(4):
        limb = f"limb{i + 1}"
        al, be = geo.tilts[i]
        rpy = pin.rpy.matrixToRpy(pin.utils.rotate("x", al) @ pin.utils.rotate("y", be))
        out += [f'  <link name="{limb}_slider"/>', f'  <link name="{limb}_cross"/>', f'  <link name="{limb}_rod"/>',
                f'  <joint name="{limb}_slide" type="prismatic">',
                f'    <parent link="base"/><child link="{limb}_slider"/>',
                f'    <origin xyz="{format_numbers(geo.columns[i])}" rpy="{format_numbers(rpy)}"/><axis xyz="0 0 1"/>{slide_lim}',
                "  </joint>",
                f'  <joint name="{limb}_u1" type="revolute">',
                f'    <parent link="{limb}_slider"/><child link="{limb}_cross"/>',
                f'    <origin xyz="0 0 0" rpy="3.1415926535897931 0 0"/><axis xyz="1 0 0"/>{lim}', "  </joint>",
                f'  <joint name="{limb}_u2" type="revolute">',
                f'    <parent link="{limb}_cross"/><child link="{limb}_rod"/>',
                f'    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>{lim}', "  </joint>",
                f'  <loop_joint name="{limb}_top" type="spherical">',
                f'    <link1 link="{limb}_rod" xyz="0 0 {format_numbers(geo.lengths[i])}" rpy="0 0 0"/>',
                f'    <link2 link="platform" xyz="{format_numbers(geo.platform_joints[i])}" rpy="0 0 0"/>',
                "  </loop_joint>"]
    out += ['  <actuated joints="limb1_slide limb2_slide limb3_slide limb4_slide"/>', "</robot>", ""]
    return "\n".join(out)


def write_urdf(geo: PCMMGeometry, path, name: str = "pcmm_4puu") -> Path:
    return write_atomic(path, build_urdf(geo, name))


def machine_robot(geo: PCMMGeometry, name: str = "pcmm_4puu") -> Robot:
    """The robot of `build_urdf(geo)`, built in memory (no file): the machine a generic Problem is about."""
    text = build_urdf(geo, name)
    robot = Robot(model=pin.buildModelFromXML(text), urdf_text=text, name=name)
    robot.loops = read_loops(robot, etree.fromstring(text.encode("utf-8")))
    return robot


def generic_parameters() -> tuple[ParameterSet, list[str]]:
    """robocal ParameterSet with the 32 generic parameters of the reduced model (all free, value 0), and
    their names in the reduced order (`pcmm_kinematics.reduced_names`)."""
    ps, names = ParameterSet(), []
    for i in range(4):
        for f in LIMB_FIELDS:
            kind, target, comp = GENERIC_MAP[f]
            target = target.format(i=i + 1)
            name = f"{target}.{comp}"
            ps.add(Parameter(name, kind, target, _INDEX[comp], unit="rad" if comp[0] == "r" else "m"))
            names.append(name)
    return ps, names


def urdf_configuration(robot, geo: PCMMGeometry, Y: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Pinocchio q of the URDF model for a closed-form solution (pose y, readings rho): a warm start."""
    q = pin.neutral(robot.model)
    m = robot.model
    for k, name in enumerate(("platform_x", "platform_y", "platform_z", "platform_rz")):
        q[m.joints[m.getJointId(name)].idx_q] = Y[k] - (geo.home[2] if k == 2 else 0.0)
    R = rz(Y[3])
    e = axis_directions(geo.tilts)[0]
    for i in range(4):
        slide = pin.utils.rotate("x", geo.tilts[i, 0]) @ pin.utils.rotate("y", geo.tilts[i, 1])
        D = geo.columns[i] + rho[i] * e[i]
        u = (Y[:3] + R @ geo.platform_joints[i] - D) / geo.lengths[i]
        w = (slide @ pin.utils.rotate("x", np.pi)).T @ u    # link direction in the U joint's home frame
        a1 = np.arctan2(-w[1], w[2])                         # Rx(a1) Ry(a2) z = w
        a2 = np.arcsin(np.clip(w[0], -1.0, 1.0))
        q[m.joints[m.getJointId(f"limb{i + 1}_slide")].idx_q] = rho[i]
        q[m.joints[m.getJointId(f"limb{i + 1}_u1")].idx_q] = a1
        q[m.joints[m.getJointId(f"limb{i + 1}_u2")].idx_q] = a2
    return q
