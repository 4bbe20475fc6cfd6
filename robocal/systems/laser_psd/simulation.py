"""Simulated acquisition: a PSD at an unknown point, a robot whose true zero offsets differ from its
nominal model, a servo that centres the spot, and noisy joint reads averaged per pose.

The controller only knows the nominal model: it plans each pose about its current estimate of the PSD
point, moves there, and servoes on the PSD reading until the spot is centred within the PSD
resolution. The image Jacobian (spot motion per flange translation across the beam) is measured by two
probe moves at each pose and refined by Broyden updates, since the PSD's orientation is unknown.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robocal.errors import InputError, RobocalError
from robocal.model.kinematics import ModelState
from robocal.model.inverse_kinematics import IKFailure, solve_ik
from robocal.systems.laser_psd.plans import PlannedPose, beam_frame, joint_limits
from robocal.residuals.base import basis_from_normal

DEG = np.pi / 180.0


@dataclass
class PSD:
    """A position-sensitive detector: centre and outward normal in the base frame (spec 1.3: 10 mm
    active diameter, 0.1 um resolution)."""

    center: np.ndarray
    normal: np.ndarray
    diameter: float = 10e-3
    resolution: float = 0.1e-6

    def __post_init__(self):
        self.center = np.asarray(self.center, dtype=float).reshape(3)
        self.R = basis_from_normal(self.normal)
        self.normal = self.R[:, 2]

    def read(self, origin, direction) -> np.ndarray | None:
        """Spot (x, y) on the PSD surface, quantised to the resolution; None when the beam misses the
        active disc or meets the surface from behind."""
        nu = self.normal @ direction
        if nu >= 0:
            return None
        t = self.normal @ (self.center - origin) / nu
        if t <= 0:
            return None
        xy = self.R[:, :2].T @ (origin + t * direction - self.center)
        if np.linalg.norm(xy) > self.diameter / 2:
            return None
        return np.round(xy / self.resolution) * self.resolution


class SimRobot:
    """Encoders at `q` (reading coordinates); the true kinematics is ModelState(robot, truth, joints)."""

    def __init__(self, robot, truth, joints, mount, reading_noise: float = 0.0, rng=None):
        self.truth = ModelState(robot, truth, joints)
        self.mount, self.noise = mount, float(reading_noise)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.q = None

    def move(self, q):
        self.q = np.asarray(q, dtype=float).copy()

    def beam(self):
        return self.mount.beam(self.truth.sample(self.q).pose(self.mount.frame))

    def read_joints(self) -> np.ndarray:
        return self.q + self.rng.normal(0.0, self.noise, len(self.q)) if self.noise > 0 else self.q.copy()


@dataclass
class ServoResult:
    q: np.ndarray
    converged: bool
    iterations: int
    spots: list = field(default_factory=list)     # PSD readings, first to last


def _translate(nominal: ModelState, frame, q, delta):
    """Joint step that moves `frame` by `delta` (base frame) on the nominal model, orientation kept."""
    s = nominal.sample(q)
    twist = np.concatenate([s.pose(frame).rotation.T @ delta, np.zeros(3)])
    return q + np.linalg.lstsq(s.frame_joint_jacobian(frame), twist, rcond=None)[0]


def servo_to_center(sim: SimRobot, psd: PSD, nominal: ModelState, tol: float | None = None,
                    gain: float = 1.0, max_iterations: int = 20, probe: float = 0.2e-3) -> ServoResult:
    """Translate the flange across the beam until |spot| <= tol on both axes (default: the resolution)."""
    tol = psd.resolution if tol is None else tol
    frame = sim.mount.frame
    spot = psd.read(*sim.beam())
    if spot is None:
        raise RobocalError("servo: the beam does not hit the PSD at the start of the pose")
    spots = [spot]
    u = nominal.sample(sim.q).pose(frame).rotation @ sim.mount.direction
    E = basis_from_normal(u)[:, :2]            # translations across the nominal beam
    q0 = sim.q
    cols = []
    for k in range(2):                         # image Jacobian by two probe moves
        sim.move(_translate(nominal, frame, q0, probe * E[:, k]))
        s = psd.read(*sim.beam())
        if s is None:
            raise RobocalError("servo: a probe move left the PSD")
        cols.append((s - spot) / probe)
    sim.move(q0)
    Jimg = np.column_stack(cols)
    for it in range(1, max_iterations + 1):
        if np.max(np.abs(spot)) <= tol:
            return ServoResult(sim.q.copy(), True, it - 1, spots)
        ab = -gain * np.linalg.solve(Jimg, spot)
        sim.move(_translate(nominal, frame, sim.q, E @ ab))
        new = psd.read(*sim.beam())
        if new is None:
            return ServoResult(sim.q.copy(), False, it, spots)
        Jimg += np.outer((new - spot) - Jimg @ ab, ab) / (ab @ ab)     # Broyden update
        spot = new
        spots.append(spot)
    return ServoResult(sim.q.copy(), bool(np.max(np.abs(spot)) <= tol), max_iterations, spots)


@dataclass
class Acquisition:
    readings: np.ndarray     # (N, n) averaged joint reads at the centred poses
    encoders: np.ndarray     # (N, n) the exact encoder positions there
    servo: list              # ServoResult per planned pose
    miss: np.ndarray         # (N,) distance of the true beam from the PSD centre, m


def average_reads(sim: SimRobot, n_reads: int) -> np.ndarray:
    """Mean of n_reads joint reads (the patent reads at least twice, the embodiment three times)."""
    if int(n_reads) != n_reads or n_reads < 2:
        raise InputError(f"n_reads must be an integer >= 2 (the method averages repeated reads), got {n_reads}",
                         field="n_reads")
    return np.mean([sim.read_joints() for _ in range(int(n_reads))], axis=0)


def acquire(robot, nominal_params, joints, sim: SimRobot, psd: PSD, plan: list[PlannedPose], direction,
            q_start, roll: float = 0.0, n_reads: int = 3, max_step: float = 10 * DEG) -> Acquisition:
    """Run the plan: plan each pose on the nominal model about the current point estimate, servo, read.

    q_start: a configuration whose true beam already hits the PSD (the operator's first jog). Moves
    larger than `max_step` go through re-centred, unrecorded waypoints so the spot never leaves the PSD.
    """
    nominal = ModelState(robot, nominal_params, joints)
    lower, upper = joint_limits(robot, joints)
    frame, mount_inv = sim.mount.frame, sim.mount.placement().inverse()
    sim.move(q_start)
    prev = PlannedPose(np.eye(3), plan[0].standoff, -1, 0.0)
    home = prev

    def centre(pose):
        r = servo_to_center(sim, psd, nominal)
        if not r.converged:
            raise RobocalError(f"servo did not centre the spot (fan {pose.fan}, {np.degrees(pose.angle):+.1f} deg)")
        o, u = sim.mount.beam(nominal.sample(sim.q).pose(frame))
        return r, o + pose.standoff * u          # the point as the nominal model sees it

    _, c_est = centre(prev)
    readings, encoders, servo, miss = [], [], [], []
    for pose in plan:
        # a new fan starts from the reference orientation: the branch of the sweep stays the planned one
        legs = [(prev, home), (home, pose)] if pose.fan != prev.fan and prev.fan >= 0 else [(prev, pose)]
        for a, b in legs:
            rel = pin.log3(b.rotation @ a.rotation.T)
            steps = max(1, int(np.ceil(np.linalg.norm(rel) / max_step)))
            for i in range(1, steps + 1):
                f = i / steps
                mid = PlannedPose(pin.exp3(f * rel) @ a.rotation, (1 - f) * a.standoff + f * b.standoff,
                                  pose.fan, pose.angle)
                try:
                    q = solve_ik(nominal, frame, beam_frame(c_est, direction, mid, roll) * mount_inv, sim.q,
                                 lower=lower, upper=upper, max_iterations=200, max_step=0.3)
                except IKFailure as exc:
                    raise RobocalError(f"pose (fan {pose.fan}, {np.degrees(pose.angle):+.1f} deg) is unreachable: "
                                       f"{exc}") from exc
                sim.move(q)
                r, c_est = centre(mid)
        servo.append(r)
        encoders.append(sim.q.copy())
        readings.append(average_reads(sim, n_reads))
        o, u = sim.beam()
        miss.append(np.linalg.norm(np.cross(psd.center - o, u)))
        prev = pose
    return Acquisition(np.array(readings), np.array(encoders), servo, np.array(miss))
