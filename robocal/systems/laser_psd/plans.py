"""Pose plans for the laser/PSD calibration: fans of beam orientations about the PSD point, and the
joint configurations that realise them (same inverse-kinematics branch along a sweep).

A planned pose is a rotation about the PSD point applied to a reference beam frame (z along the beam,
pointing at the point from `standoff` away), so every planned beam passes through the point. The
patent's protocol is one fan: +30 deg to -30 deg in equal steps, 7 poses (spec 3.2). The spec's
simulations (6.5) add: several fan axes, wider angles, varied stand-offs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.errors import InputError, RobocalError
from robocal.model.inverse_kinematics import IKFailure, solve_ik
from robocal.residuals.base import basis_from_normal

DEG = np.pi / 180.0


@dataclass
class PlannedPose:
    rotation: np.ndarray     # (3, 3) about the PSD point, applied to the reference beam frame
    standoff: float          # laser origin to PSD point along the beam, m
    fan: int
    angle: float             # rad, within the fan


def _axis(axis) -> np.ndarray:
    a = np.asarray(axis, dtype=float).reshape(3)
    if not np.all(np.isfinite(a)) or np.linalg.norm(a) < 1e-9:
        raise InputError("a fan axis must be a non-zero vector", field="axis")
    return a / np.linalg.norm(a)


def fan(axis, start: float = 30 * DEG, stop: float = -30 * DEG, n: int = 7, standoffs=0.35,
        fan_index: int = 0) -> list[PlannedPose]:
    """n poses tilted about `axis` (base frame, through the PSD point) from `start` to `stop` in equal
    steps of (start - stop)/(n - 1). standoffs: one value or one per pose (vary it to see the direction
    of the beam in the flange frame)."""
    if int(n) != n or n < 2:
        raise InputError(f"a fan needs at least 2 poses, got {n}", field="n")
    if start == stop:
        raise InputError("a fan needs start != stop", field="start")
    a = _axis(axis)
    s = np.broadcast_to(np.asarray(standoffs, dtype=float), (int(n),))
    if np.any(s <= 0):
        raise InputError("stand-offs must be positive", field="standoffs")
    return [PlannedPose(pin.exp3(a * t), float(si), fan_index, float(t))
            for t, si in zip(np.linspace(start, stop, int(n)), s)]


def patent_fan(axis=(1.0, 0.0, 0.0), tilt: float = 30 * DEG, n: int = 7, standoff: float = 0.35):
    """The patent's protocol: +tilt .. -tilt (tilt in 30..60 deg) in n equal steps."""
    if not 30 * DEG - 1e-12 <= tilt <= 60 * DEG + 1e-12:
        raise InputError(f"the patent tilts 30 to 60 deg, got {np.degrees(tilt):.3g} deg", field="tilt")
    return fan(axis, tilt, -tilt, n, standoff)


def multi_fan(axes=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), half_angle: float = 45 * DEG,
              n_per_fan: int = 7, standoffs=0.35) -> list[PlannedPose]:
    """One fan of n_per_fan poses (+half_angle .. -half_angle) about each axis."""
    out = []
    for k, ax in enumerate(axes):
        out += fan(ax, half_angle, -half_angle, n_per_fan, standoffs, fan_index=k)
    return out


def beam_frame(target, direction, pose: PlannedPose, roll: float = 0.0) -> pin.SE3:
    """Beam frame (origin at the laser, z along the beam) of a planned pose in the base frame.
    `direction`: the reference beam direction; `roll`: spin of the reference frame about it."""
    R_ref = basis_from_normal(direction) @ pin.exp3(np.array([0.0, 0.0, roll]))
    R = pose.rotation @ R_ref
    return pin.SE3(R, np.asarray(target, dtype=float) - pose.standoff * R[:, 2])


def joint_limits(robot, joints) -> tuple[np.ndarray, np.ndarray]:
    """The model's position limits (a wrist may turn beyond +-pi); unbounded ones become +-2 pi."""
    ids = [robot.model.joints[robot.joint_id(j)].idx_q for j in joints]
    lo, hi = robot.model.lowerPositionLimit[ids], robot.model.upperPositionLimit[ids]
    return np.where(np.isfinite(lo), lo, -2 * np.pi), np.where(np.isfinite(hi), hi, 2 * np.pi)


def _seeds(n: int, azimuth: float):
    # deterministic grid around "facing the target": the first one that converges well is used
    grid = (0.0, 0.8, -0.8, 1.6, -1.6)
    for rest in np.array(np.meshgrid(*[grid] * (n - 1), indexing="ij")).reshape(n - 1, -1).T:
        yield np.concatenate([[azimuth], rest])


def plan_configurations(robot, ms, joints, mount, plan: list[PlannedPose], target, direction,
                        roll: float = 0.0, seed=None, min_sigma: float = 0.05) -> np.ndarray:
    """(N, len(joints)) readings realising the plan on the model `ms` (exact up to the IK tolerance).

    The reference pose (no rotation) is solved first from `seed` or a deterministic seed grid (of the
    solutions whose Jacobian's smallest singular value exceeds `min_sigma`, the one farthest from the
    joint limits); each fan is then walked from
    its pose nearest the reference outwards, each pose seeded with its neighbour.
    """
    lower, upper = joint_limits(robot, joints)
    mount_inv = mount.placement().inverse()

    def flange(pose):
        return beam_frame(target, direction, pose, roll) * mount_inv

    ref = PlannedPose(np.eye(3), plan[0].standoff if plan else 0.35, -1, 0.0)
    seeds = [np.asarray(seed, float)] if seed is not None else _seeds(len(joints), np.arctan2(target[1], target[0]))
    mid, half = (upper + lower) / 2, (upper - lower) / 2
    found = []
    for k, sd in enumerate(seeds):
        if k >= 40 or len(found) >= 6:
            break
        try:
            q = solve_ik(ms, mount.frame, flange(ref), sd, lower=lower, upper=upper, tol=1e-10, max_iterations=60,
                             max_step=0.3)
        except IKFailure:
            continue      # this seed leads nowhere; the grid has others
        if np.linalg.svd(ms.sample(q).frame_joint_jacobian(mount.frame),
                                           compute_uv=False)[-1] > min_sigma:
            found.append(q)
    # the branch farthest from every joint limit leaves the sweeps the most room
    q_ref = min(found, key=lambda q: np.max(np.abs(q - mid) / half)) if found else None
    if q_ref is None:
        raise RobocalError("no inverse-kinematics solution for the reference pose of the plan (unreachable?)")
    out = np.zeros((len(plan), len(joints)))
    for f in sorted({p.fan for p in plan}):
        idx = [k for k, p in enumerate(plan) if p.fan == f]
        centre = min(idx, key=lambda k: abs(plan[k].angle))
        order = sorted(idx, key=lambda k: (abs(k - centre)))
        for k in order:
            nb = [m for m in (k - 1, k + 1) if m in idx and abs(m - centre) < abs(k - centre)]
            q0 = out[nb[0]] if nb else q_ref
            # big jumps are walked in small rotations so the branch cannot flip
            q = _walk(ms, mount.frame, lower, upper, q0, flange, plan[nb[0]] if nb else ref, plan[k])
            if q is None:
                raise RobocalError(f"pose {k} of the plan (fan {f}, {np.degrees(plan[k].angle):+.1f} deg) is "
                                   f"unreachable from its neighbour")
            out[k] = q
    return out


def _walk(ms, frame, lower, upper, q0, flange, a: PlannedPose, b: PlannedPose, max_step=5 * DEG):
    rel = pin.log3(b.rotation @ a.rotation.T)
    steps = max(1, int(np.ceil(np.linalg.norm(rel) / max_step)))
    q = q0
    for i in range(1, steps + 1):
        f = i / steps
        mid = PlannedPose(pin.exp3(f * rel) @ a.rotation, (1 - f) * a.standoff + f * b.standoff, b.fan, b.angle)
        try:
            q = solve_ik(ms, frame, flange(mid), q, lower=lower, upper=upper, max_iterations=200, max_step=0.3)
        except IKFailure:
            return None
    return q
