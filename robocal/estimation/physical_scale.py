"""How large each robot parameter can physically be: the scale of the default prior and of the checks.

A robot's geometric errors are a small fraction of its size, and its joint-zero and axis errors a few
milliradians; the scales below say so, per parameter kind, for any robot (docs/validation.md):

  length (placement tx..tz, prismatic offset, backlash in m)   LENGTH_FRACTION x robot size
  angle  (placement rx..rz, revolute offset, backlash in rad)  ANGLE_SCALE
  load   (compliance, tilt: rad per N m)                       ANGLE_SCALE / largest gravity moment at the joint

The robot size is the largest distance between the origins of the read joints (and the root) in the
nominal zero configuration of the URDF. The frames the config lets float to register the robot with the
measurement (base, measurement set-up, the measured tool frames) have no physical scale: they may be
anywhere; a calibrated frame that no measurement looks at (a loop's attachment) is robot geometry.
Transmission parameters (screw lead, ratio) have none either; they are left to the data. A residual may give
some of its set-up quantities a scale of its own (`Residual.aux_scales`: a camera's intrinsics, within a few per
cent of their prior calibration); they are still registered with the frames, and get the default prior too.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.model.parameters import Parameter

LENGTH_FRACTION = 0.01      # geometric errors within 1 % of the robot's size
ANGLE_SCALE = 0.01          # 10 mrad: joint zeros and axis directions within about half a degree
BEYOND = 10.0               # a fitted value this many scales from nominal is not a robot any more
MIN_SIZE = 0.05             # m: floor of the robot size (a single joint has no spread of origins)
MIN_LOAD = 1e-3             # N m: below this a joint carries no load worth a compliance scale
REGISTRATION_KINDS = ("base", "session_frame", "auxiliary")   # plus the placement of a measured (tool) frame
ROBOT_KINDS = ("joint_placement", "joint_offset", "joint_compliance", "joint_backlash", "joint_tilt",
               "frame_placement")                 # a frame on the robot that no measurement looks at
DETERMINED_LENGTH = 1e-4    # m: a parameter known to 0.1 mm is determined ...
DETERMINED_ANGLE = 1e-4     # rad: ... and one known to 0.1 mrad


def measured_frames(problem) -> set[str]:
    """Frames measurements look at, and (as "param:<name>") residual unknowns that are machine geometry."""
    frames = {f for r in problem.residuals for f in [getattr(r, "frame", None)] if isinstance(f, str)}
    return frames | {f"param:{n}" for r in problem.residuals for n in r.machine_parameter_names()}


def is_registration(p: Parameter, measured: set[str]) -> bool:
    """Base, measurement set-up, or the placement of a frame a measurement looks at (the tool); not the
    unknowns of a residual that models the machine itself (a parallel CMM's reduced error parameters)."""
    if f"param:{p.name}" in measured:
        return False
    return p.kind in REGISTRATION_KINDS or (p.kind == "frame_placement" and p.target in measured)


def robot_size(robot, joint_names) -> float:
    """Largest distance (m) between the origins of `joint_names` and the root, nominal zero configuration."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, pin.neutral(robot.model))
    pts = [np.zeros(3)] + [data.oMi[robot.joint_id(j)].translation.copy() for j in joint_names]
    pts = np.array(pts)
    spread = np.max(np.linalg.norm(pts[:, None] - pts[None], axis=2)) if len(pts) > 1 else 0.0
    return max(float(spread), MIN_SIZE)


def joint_loads(robot, joint_names, values) -> dict[str, float]:
    """Largest gravity moment (N m, full 3D moment of the subtree about the joint origin) over `values`."""
    model = robot.model
    data = model.createData()
    g = model.gravity.linear
    loads = {j: 0.0 for j in joint_names}
    qmap = [(robot.joint_id(j), model.joints[robot.joint_id(j)].idx_q) for j in joint_names]
    for row in np.atleast_2d(values):
        q = pin.neutral(model)
        for (jid, iq), v in zip(qmap, row):
            if model.joints[jid].nq == 1:
                q[iq] = v
        pin.centerOfMass(model, data, q, False)
        pin.forwardKinematics(model, data, q)
        for j, (jid, _) in zip(joint_names, qmap):
            arm = data.com[jid] - data.oMi[jid].translation
            loads[j] = max(loads[j], float(np.linalg.norm(np.cross(arm, data.mass[jid] * g))))
    return loads


@dataclass
class PhysicalScales:
    """Per parameter name: its physical scale and the standard error below which it counts as determined."""

    size: float
    scale: dict[str, float]
    determined: dict[str, float]

    def of(self, names) -> np.ndarray:
        return np.array([self.scale.get(n, np.inf) for n in names])

    def threshold(self, names) -> np.ndarray:
        return np.array([self.determined.get(n, np.inf) for n in names])


def is_length(p: Parameter) -> bool:
    return p.unit == "m" or p.unit.startswith("m/")


def physical_scales(problem, det_length: float = DETERMINED_LENGTH, det_angle: float = DETERMINED_ANGLE,
                    length_fraction: float = LENGTH_FRACTION, angle_scale: float = ANGLE_SCALE) -> PhysicalScales:
    """Scales of the robot-kind parameters of `problem.params` (others: none, i.e. infinite)."""
    robot, params = problem.robot, problem.params
    joints = [j for j in problem.joint_names if j in robot.joint_names]
    size = robot_size(robot, joints)
    needs_load = any(p.kind in ("joint_compliance", "joint_tilt") for p in params)
    loads = joint_loads(robot, joints, problem.values) if needs_load else {}
    scale, det = {}, {}
    measured = measured_frames(problem)
    # set-up quantities with a physical scale of their own (a camera's intrinsics): the residual says it
    declared = {n: v for r in problem.residuals for n, v in r.aux_scales().items()}
    for p in params:
        if p.name in declared:
            scale[p.name], det[p.name] = declared[p.name]
            continue
        if is_registration(p, measured):
            if p.unit in ("m", "rad"):
                det[p.name] = det_length if p.unit == "m" else det_angle      # determinable, never out of scale
            continue
        if p.kind not in ROBOT_KINDS:
            continue
        if p.kind in ("joint_compliance", "joint_tilt"):
            load = loads.get(p.target, 0.0)
            if load < MIN_LOAD:
                continue          # no load: the data cannot see it and no scale applies
            # a compliance of this size bends the joint by the angle scale under its largest load
            ref_angle = length_fraction * size if is_length(p) else angle_scale
            scale[p.name], det[p.name] = ref_angle / load, (det_length if is_length(p) else det_angle) / load
        elif is_length(p):
            scale[p.name], det[p.name] = length_fraction * size, det_length
        else:
            scale[p.name], det[p.name] = angle_scale, det_angle
    return PhysicalScales(size, scale, det)


def unit_label(p: Parameter) -> tuple[float, str]:
    """Report scale and unit of a parameter: mm for lengths, mrad for angles, else SI."""
    if p.unit == "m":
        return 1e3, "mm"
    if p.unit == "rad":
        return 1e3, "mrad"
    if p.unit == "rad/(N m)":
        return 1e3, "mrad/(N m)"
    return 1.0, p.unit
