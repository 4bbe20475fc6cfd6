"""MJCF of a Stewart (6-UPS) platform: the same machine as `mechanism.build_urdf`, as MuJoCo writes closed loops.

    <worldbody> base (one root body: Pinocchio 4.1 reads only the first)
        leg{j}_cross (hinge x leg{j}_u1) > leg{j}_cylinder (hinge y leg{j}_u2) > leg{j}_rod (slide z leg{j}_slide)
        platform (freejoint platform_float) > tool
    <equality> connect leg{j}_top: site leg{j}_rod_end (rod origin) == site leg{j}_platform_ball (T_j, platform)
    <actuator> position joint=leg{j}_slide

Legs come before the platform so that Pinocchio numbers the joints as it does for the URDF. The connects name
both anchors by sites: MuJoCo's body form takes body2's anchor from the initial configuration, where this
machine's loops are open (a strut at 0 is o_j long, not the home length). Loaded by robocal.model.mjcf.load_mjcf,
it gives the parameters of the URDF with the same meaning (tests/test_loops_mjcf.py).
"""
from __future__ import annotations

from pathlib import Path

import pinocchio as pin

from robocal.io.text_files import format_numbers, write_atomic
from robocal.systems.stewart.mechanism import StewartGeometry, aim_z

HALF_PI = "1.5707963267948966"


def _quaternion(R) -> str:
    q = pin.Quaternion(R)
    return format_numbers([q.w, q.x, q.y, q.z])       # MJCF order: w x y z


def build_mjcf(geometry: StewartGeometry, name: str = "stewart") -> str:
    """MJCF text (tree + connect equalities + actuators) of a Stewart platform."""
    N, T, o = geometry.leg_base, geometry.leg_platform, geometry.offsets
    home_tips = geometry.home + T
    out = ['<?xml version="1.0"?>',
           f'<mujoco model="{name}">',
           "  <!-- Written by robocal.systems.stewart.mjcf.build_mjcf. Units: m, rad.",
           "       N_j = pos of body leg{j}_cross; T_j = pos of site leg{j}_platform_ball (platform frame);",
           "       o_j = pos z of body leg{j}_rod, whose slide position is the strut coordinate s_j. -->",
           '  <compiler angle="radian"/>', "  <worldbody>", '    <body name="base">']
    for j in range(6):
        leg = f"leg{j + 1}"
        out += [f'      <body name="{leg}_cross" pos="{format_numbers(N[j])}" '
                f'quat="{_quaternion(aim_z(home_tips[j] - N[j]))}">',
                f'        <joint name="{leg}_u1" type="hinge" axis="1 0 0" range="-{HALF_PI} {HALF_PI}"/>',
                f'        <body name="{leg}_cylinder">',
                f'          <joint name="{leg}_u2" type="hinge" axis="0 1 0" range="-{HALF_PI} {HALF_PI}"/>',
                f'          <body name="{leg}_rod" pos="0 0 {format_numbers(o[j])}">',
                f'            <joint name="{leg}_slide" type="slide" axis="0 0 1" '
                f'range="{format_numbers(-o[j])} {format_numbers(o[j])}"/>',
                f'            <site name="{leg}_rod_end" pos="0 0 0"/>',
                "          </body>", "        </body>", "      </body>"]
    out += [f'      <body name="platform" pos="{format_numbers(geometry.home)}">',
            '        <freejoint name="platform_float"/>',
            f'        <body name="tool" pos="{format_numbers(geometry.tool)}"/>']
    out += [f'        <site name="leg{j + 1}_platform_ball" pos="{format_numbers(T[j])}"/>' for j in range(6)]
    out += ["      </body>", "    </body>", "  </worldbody>", "  <equality>"]
    out += [f'    <connect name="leg{j + 1}_top" site1="leg{j + 1}_rod_end" site2="leg{j + 1}_platform_ball"/>'
            for j in range(6)]
    out += ["  </equality>", "  <actuator>"]
    out += [f'    <position name="leg{j + 1}_motor" joint="leg{j + 1}_slide"/>' for j in range(6)]
    out += ["  </actuator>", "</mujoco>", ""]
    return "\n".join(out)


def write_mjcf(geometry: StewartGeometry, path: str | Path, name: str = "stewart") -> Path:
    return write_atomic(path, build_mjcf(geometry, name))
