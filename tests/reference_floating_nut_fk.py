"""Plain reference of the floating-nut hexapod kinematics (docs/floating_nut_hexapod.md): the compensated IK
written leg by leg with explicit elementary rotations, and forward kinematics by Newton with a central-difference
Jacobian. Slow and independent of robocal's solvers; only tests/test_floating_nut_fk_reference.py uses it."""
import math

import numpy as np


def rotation(angles, euler):
    a, b, g = angles
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rz = np.array([[math.cos(g), -math.sin(g), 0], [math.sin(g), math.cos(g), 0], [0, 0, 1]])
    return rz @ ry @ rx if euler == "ZYX-fixed" else rx @ ry @ rz


def leg_terms(geometry, pose):
    """(effective length l_i, dihedral phi_i) of each leg at one pose."""
    R = rotation(pose[3:], geometry.euler)
    out = []
    for i in range(6):
        u = pose[:3] + R @ geometry.m[i] - geometry.b[i]
        length = np.linalg.norm(u)
        nb, nm = np.cross(geometry.base_axes[i], u), np.cross(R @ geometry.plat_axes[i], u)
        out.append((length, math.atan2(np.cross(nb, nm) @ (u / length), nb @ nm)))
    return np.array(out)


def command_lengths(geometry, pose, compensate=True):
    """l_c = l + sigma lead theta / (2 pi), theta = phi - phi(p0) wrapped to (-pi, pi]; or l."""
    terms, home = leg_terms(geometry, np.asarray(pose, float)), leg_terms(geometry, geometry.p0)
    if not compensate:
        return terms[:, 0]
    theta = -((math.pi - (terms[:, 1] - home[:, 1])) % (2 * math.pi) - math.pi)
    return terms[:, 0] + geometry.sigma * geometry.lead * theta / (2 * math.pi)


def forward(geometry, lengths, compensate=True, h=1e-7):
    """Pose with command_lengths(pose) = lengths, Newton from p0 until the step is at round-off."""
    p = np.array(geometry.p0, dtype=float)
    for _ in range(100):
        e = lengths - command_lengths(geometry, p, compensate)
        J = np.column_stack([(command_lengths(geometry, p + h * d, compensate)
                              - command_lengths(geometry, p - h * d, compensate)) / (2 * h) for d in np.eye(6)])
        step = np.linalg.solve(J, e)
        p = p + step
        if np.abs(step).max() < 1e-14:
            return p
    raise RuntimeError("reference FK did not converge")
