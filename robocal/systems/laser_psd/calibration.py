"""Zero-offset self-calibration with a laser on the flange and a PSD at an unknown point (docs/laser_psd.md).

The robot is servoed until its beam hits the PSD centre from many orientations; the joint readings are
the data and "every beam passes through one point" is the model (robocal.residuals.laser_line, with the
point as auxiliary unknowns). This module builds that Problem, propagates joint-reading noise to the
estimates, and turns the generic identifiability result into sentences about this set-up. Pose plans are
in laser_psd_plans, the acquisition simulation in laser_psd_simulation, the patent's pairwise objective
in laser_psd_pairwise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.model.kinematics import ModelState
from robocal.systems.laser_psd.pairwise import PairwiseScatterResidual, eligible_pairs, lsq_point
from robocal.model.parameters import ParameterSet, robot_parameters
from robocal.estimation.calibrate import calibrate
from robocal.estimation.problem import Problem
from robocal.residuals.base import basis_from_normal
from robocal.residuals.laser_line import LaserLineResidual

RESIDUAL = "psd"


@dataclass
class LaserMount:
    """The beam in the flange frame: a point on it and its direction (normalised here), SI units."""

    origin: np.ndarray
    direction: np.ndarray
    frame: str = "tool0"

    def __post_init__(self):
        self.origin = np.asarray(self.origin, dtype=float).reshape(3)
        d = np.asarray(self.direction, dtype=float).reshape(3)
        if not np.all(np.isfinite(d)) or np.linalg.norm(d) < 1e-9:
            raise InputError("the laser direction must be a non-zero vector", field="direction")
        self.direction = d / np.linalg.norm(d)

    def placement(self) -> pin.SE3:
        """Beam frame in the flange frame: origin on the beam, z along it."""
        return pin.SE3(basis_from_normal(self.direction), self.origin.copy())

    def beam(self, flange: pin.SE3) -> tuple[np.ndarray, np.ndarray]:
        """(origin, unit direction) of the beam in the frame `flange` is expressed in."""
        return flange.act(self.origin), flange.rotation @ self.direction


def beams(robot, params: ParameterSet, joints, readings, mount: LaserMount) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) origins and (N, 3) directions of the beams at the readings, for the model `params`."""
    ms = ModelState(robot, params, joints)
    lines = [mount.beam(ms.sample(v).pose(mount.frame)) for v in np.atleast_2d(readings)]
    return np.array([o for o, _ in lines]), np.array([u for _, u in lines])


def zero_offset_problem(robot, joints, readings, mount: LaserMount, sigma: float = 1e-5,
                        fixed_joints=(), mount_free: bool = False, preset: str = "offsets",
                        frames=None, target_guess=None) -> Problem:
    """The Problem "all beams pass through one unknown point" over the readings (N, len(joints)), SI.

    Every joint's offset is requested unless listed in `fixed_joints`, so that the calibration reports
    the ones these data cannot give (joint 1 always, joint 6 for a coaxial beam) instead of guessing.
    mount_free: estimate the beam's origin and direction in the flange frame too (auxiliary unknowns,
    which the identifiability order keeps ahead of the joints). The PSD point starts at the least-squares
    intersection of the nominal beams unless `target_guess` is given.
    """
    readings = np.atleast_2d(np.asarray(readings, dtype=float))
    if readings.shape[1] != len(joints):
        raise InputError(f"{readings.shape[1]} joint readings per pose for {len(joints)} joints", field="readings")
    if len(readings) < 3:
        raise InputError(f"{len(readings)} poses: at least 3 beams are needed to locate a point",
                         field="readings")
    params = robot_parameters(robot, joints, preset, frames=frames)
    for j in fixed_joints:
        params.fix(f"{j}.offset")
    if target_guess is None:
        target_guess = lsq_point(*beams(robot, params, joints, readings, mount))[0]
    res = LaserLineResidual(RESIDUAL, mount.frame, np.arange(len(readings)), target=target_guess,
                            origin=mount.origin, direction=mount.direction, target_unknown=True,
                            beam_unknown=mount_free, sigma=sigma)
    return Problem(robot, params, joints, readings, [res])


def pairwise_problem(robot, joints, readings, mount: LaserMount, sigma: float = 1e-5, fixed_joints=(),
                     min_angle: float = np.radians(2.0)) -> Problem:
    """The patent's objective (pairwise midpoints about their centroid) on the same data, for comparison.
    Pairs closer than `min_angle` at the nominal model are skipped."""
    readings = np.atleast_2d(np.asarray(readings, dtype=float))
    params = robot_parameters(robot, joints, "offsets")
    for j in fixed_joints:
        params.fix(f"{j}.offset")
    _, U = beams(robot, params, joints, readings, mount)
    res = PairwiseScatterResidual("psd_pairs", mount.frame, eligible_pairs(U, min_angle), mount.origin,
                                  mount.direction, sigma)
    return Problem(robot, params, joints, readings, [res])


def reading_noise_covariance(problem: Problem, sigma_q) -> np.ndarray:
    """Covariance of the free parameters caused by Gaussian joint-reading noise sigma_q (rad, per joint).

    The fit weights every residual row equally (the residual cannot carry a per-pose 2x2 covariance), so
    the estimate is ordinary least squares and its covariance is the sandwich
    (J^T J)^-1 J^T S J (J^T J)^-1 with S = A Sigma_q A^T per pose, A = d r / d readings. Linearised at
    the problem's current parameters.
    """
    sigma_q = np.broadcast_to(np.asarray(sigma_q, dtype=float), (len(problem.joint_names),))
    ev = problem.evaluate()
    states = problem.states()
    blocks = []
    for res in problem.residuals:
        aux = problem.aux_values(res)
        scale = res.row_scale()
        keep = scale != 0
        for k in range(res.n_terms):
            t = res.evaluate(k, states, aux)
            by_sample: dict[int, np.ndarray] = {}
            for i, frame, D in t.frames:
                by_sample[i] = by_sample.get(i, 0) + D @ states[i].frame_joint_jacobian(frame)
            blocks.append([((Ai * scale[:, None])[keep], i) for i, Ai in by_sample.items()])
    # S = sum over samples of (rows' derivative w.r.t. that sample's readings) Sigma_q (...)^T
    m = len(ev.r)
    Jq = np.zeros((m, len(problem.values) * len(sigma_q)))
    row = 0
    for term in blocks:
        h = term[0][0].shape[0]
        for Ai, i in term:
            Jq[row:row + h, i * len(sigma_q):(i + 1) * len(sigma_q)] += Ai * sigma_q[None, :]
        row += h
    pinvJ = np.linalg.pinv(ev.J)
    G = pinvJ @ Jq
    return G @ G.T


@dataclass
class OffsetReport:
    """Offsets in degrees, for people: estimate, its standard error and whether the data gave it."""

    joint: str
    value_deg: float
    stderr_deg: float | None
    identified: bool


def offset_report(result, joints) -> list[OffsetReport]:
    out = []
    for j in joints:
        p = result.params[f"{j}.offset"]
        ident = p.name in result.estimated
        se = np.degrees(p.stderr) if ident and p.stderr is not None and np.isfinite(p.stderr) else None
        out.append(OffsetReport(j, float(np.degrees(p.value)), se, ident))
    return out


def _coaxial(mount: LaserMount, robot) -> bool:
    """Beam on the last joint's axis (z of the joint frame, expressed in the mount frame)."""
    f = robot.model.frames[robot.frame_id(mount.frame)]
    fMj = f.placement.inverse()                   # last joint frame in the mount frame
    axis, point = fMj.rotation[:, 2], fMj.translation
    parallel = np.linalg.norm(np.cross(axis, mount.direction)) < 1e-9
    on_axis = np.linalg.norm(np.cross(mount.origin - point, axis)) < 1e-9
    return parallel and on_axis


def _scale_is_free(problem: Problem, res: LaserLineResidual, free: set[str]) -> bool:
    """Every length of the chain, the mount and the PSD point free: then multiplying them all by one
    factor keeps every beam through the point (the residual is homogeneous of degree 1 in lengths)."""
    robot = problem.robot

    def all_free(prefix, comps=("tx", "ty", "tz")):
        return all(f"{prefix}.{c}" in free for c in comps)

    aux = {a.suffix: a for a in res.aux}
    if not all(f"{res.name}.target.{c}" in free for c in "xyz"):
        return False
    mount_free = all(f"{res.name}.origin.{c}" in free for c in "xyz")
    for j in robot.supporting_joints(res.frame):
        p = robot.model.jointPlacements[robot.joint_id(j)].translation
        if np.linalg.norm(p) > 0 and not all_free(j):
            return False
    offset = robot.model.frames[robot.frame_id(res.frame)].placement.translation
    if np.linalg.norm(offset) > 0 and not (all_free(res.frame) or mount_free):
        return False
    origin = np.array([aux[f"origin.{c}"].value for c in "xyz"])
    return np.linalg.norm(origin) == 0 or mount_free


@dataclass
class LaserCalibration:
    result: object                   # robocal CalibrationResult
    statements: list[str]


def calibrate_laser(problem: Problem, mount: LaserMount, options=None) -> LaserCalibration:
    """robocal.estimation.calibrate.calibrate plus the laser sentences. No special-casing: the residual is invariant
    to a spin about the beam, so the generic selection itself drops joint 6 when it is such a spin."""
    result = calibrate(problem, options)
    return LaserCalibration(result, laser_statements(result, problem, mount))


def laser_statements(result, problem: Problem, mount: LaserMount) -> list[str]:
    """What these data cannot give, in words, built on the generic identifiability result."""
    joints = problem.joint_names
    res = next(r for r in problem.residuals if isinstance(r, LaserLineResidual))
    lost = set(result.unidentifiable)
    out = []
    first, last = joints[0], joints[-1]
    explained = set()          # losses a sentence above already gives the reason for
    if f"{first}.offset" in lost:
        out.append(f"The zero offset of {first} cannot be found with an unknown PSD location: turning {first} "
                   f"turns every beam about the base axis, and the unknown point turns with them, so the data do "
                   f"not change. It is left at its initial value; it needs an external azimuth reference.")
    if f"{last}.offset" in lost:
        if _coaxial(mount, problem.robot):
            explained.add(f"{last}.offset")
            out.append(f"The zero offset of {last} cannot be found: the beam lies on {last}'s axis, so turning "
                       f"{last} spins the beam about itself. Mount the laser off the axis or tilted to it.")
        elif any(f"{res.name}.{s}" in result.requested for s in ("origin.x", "origin.y", "tilt_a", "tilt_b")):
            explained.add(f"{last}.offset")
            out.append(f"The zero offset of {last} cannot be separated from the laser mount's orientation "
                       f"about {last}'s axis, which is estimated too. Calibrate the mount beforehand to get it.")
    for name in sorted(lost - explained):
        j = name[:-len(".offset")] if name.endswith(".offset") else None
        if j in joints[1:]:
            out.append(f"The zero offset of {j} cannot be found from these poses: a turn of {j} moves every "
                       f"beam and the point rigidly together (its axis did not move between poses). Vary "
                       f"{first} across the poses (fans about several axes).")
    if f"{res.name}.origin.z" in lost or any(n.startswith(f"{res.name}.origin") for n in lost):
        out.append("The laser origin can only be found across the beam: sliding it along the beam changes "
                   "nothing.")
    if any(n.startswith(f"{res.name}.tilt") for n in lost):
        out.append("The beam direction in the flange frame cannot be found: with a constant stand-off the data "
                   "fix only one point of the beam. Vary the laser-to-PSD distance.")
    if _scale_is_free(problem, res, set(result.requested)):
        out.append("The overall length scale cannot be determined: beams through one point stay so when every "
                   "length (links, laser mount, PSD position) is multiplied by the same factor. Hold one length "
                   "fixed or add a distance measurement.")
    offsets = [o for o in offset_report(result, joints) if o.identified and o.stderr_deg is not None]
    if offsets:
        worst = max(offsets, key=lambda o: o.stderr_deg)
        out.append(f"Weakest offset: {worst.joint}, standard error {worst.stderr_deg:.2g} deg.")
    return out
