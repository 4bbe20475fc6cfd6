"""How large each robot parameter can physically be: the scale of the default prior and of the checks.

A robot's geometric errors are a small fraction of its size, and its joint-zero and axis errors a few
milliradians; the scales below say so, per parameter kind, for any robot (docs/validation.md, where each
formula is argued):

  length (placement tx..tz, prismatic offset)         LENGTH_FRACTION x robot size
  angle  (placement rx..rz, revolute offset)          ANGLE_SCALE
  backlash (signed half-play b; the play is 2|b|)     ANGLE_SCALE / 2 (revolute), LENGTH_FRACTION x size / 2
  compliance (rad/(N m), m/N)                         ANGLE_SCALE (or the length scale) / reference load, the
                                                      reference load the joint's effort limit from the URDF;
                                                      without one (or one below the gravity load the joint
                                                      carries in the data), the largest gravity torque (force)
                                                      along its axis over the samples
  tilt (rad/(N m))                                    ANGLE_SCALE / the largest gravity moment across the
                                                      joint axis over the samples (no URDF field rates a bearing)
  transmission (screw lead, coupling ratio)           LENGTH_FRACTION x |its nominal value| (relative 1 %)

The robot size is the largest distance between the origins of the read joints (and the root) in the
nominal zero configuration of the URDF. The frames the config lets float to register the robot with the
measurement (base, measurement set-up, the measured tool frames) have no physical scale: they may be
anywhere; a calibrated frame that no measurement looks at (a loop's attachment) is robot geometry.
Transmission parameters (screw lead, ratio) have none either; they are left to the data. A residual may give
some of its set-up quantities a scale of its own (`Residual.aux_scales`: a camera's intrinsics, within a few per
cent of their prior calibration); they are still registered with the frames, and get the default prior too.
Each scale has a threshold DETERMINED_* / scale-units below it (0.1 mm, 0.1 mrad, or the same deflection at
the reference load): a standard error below it counts as determined (robocal.estimation.determinacy).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robocal.model.parameters import Parameter

LENGTH_FRACTION = 0.01      # geometric errors within 1 % of the robot's size
ANGLE_SCALE = 0.01          # 10 mrad: joint zeros and axis directions within about half a degree
BEYOND = 10.0               # a fitted value this many scales from nominal is not a robot any more ...
FINDING_SCALES = 3.0        # k: ... and one beyond this many scales that the data determine is a finding
FINDING_SIGMAS = 4.0        # m: "determined": its distance from nominal exceeds m data-only standard errors
MIN_SIZE = 0.05             # m: floor of the robot size (a single joint has no spread of origins)
MIN_LOAD = 1e-3             # N m: below this a joint carries no load worth a compliance or tilt scale
REGISTRATION_KINDS = ("base", "session_frame", "auxiliary")   # plus the placement of a measured (tool) frame
ROBOT_KINDS = ("joint_placement", "joint_offset", "joint_compliance", "joint_backlash", "joint_tilt",
               "frame_placement", "transmission")  # frame_placement: a frame on the robot no measurement sees
DETERMINED_LENGTH = 1e-4    # m: a parameter known to 0.1 mm is determined ...
DETERMINED_ANGLE = 1e-4     # rad: ... and one known to 0.1 mrad
DETERMINED_RELATIVE = 1e-4  # a transmission ratio or lead known to 0.01 % of its value


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
    pts = [np.zeros(3)] + [joint_origin(robot.model, robot.joint_id(j)).translation.copy() for j in joint_names]
    pts = np.array(pts)
    spread = np.max(np.linalg.norm(pts[:, None] - pts[None], axis=2)) if len(pts) > 1 else 0.0
    return max(float(spread), MIN_SIZE)


def joint_origin(model, jid: int) -> pin.SE3:
    """Joint jid's placement at the neutral configuration, where every joint's own motion is the identity: the
    product of the joint placements from the root (forward kinematics' own products, without a Data)."""
    chain = []
    while jid > 0:
        chain.append(jid)
        jid = model.parents[jid]
    M = pin.SE3.Identity()
    for j in reversed(chain):
        M = M * model.jointPlacements[j]
    return M


@dataclass
class JointLoads:
    """Per joint, the largest gravity load over the samples (nominal model, static): along the axis (the
    torque of a revolute joint, N m; the force of a prismatic one, N) and across it (the moment a bearing or
    column carries, N m), and the effort limit the URDF states (0: none)."""

    along: dict[str, float]
    across: dict[str, float]
    effort: dict[str, float]


def joint_configuration(model, qmap, row) -> np.ndarray:
    q = pin.neutral(model)
    for (iq, nq), v in zip(qmap, row):
        if nq == 1:
            q[iq] = v
        elif nq == 2:                      # a continuous joint: (cos, sin)
            q[iq:iq + 2] = np.cos(v), np.sin(v)
    return q


def joint_loads(robot, joint_names, values) -> JointLoads:
    """Gravity loads of the one-dof joints `joint_names` over the readings `values` (RNEA at rest)."""
    model = robot.model
    data = model.createData()
    ids = [robot.joint_id(j) for j in joint_names]
    qmap = [(model.joints[i].idx_q, model.joints[i].nq) for i in ids]
    axes = {j: robot.joint_axis(i) for j, i in zip(joint_names, ids)}
    along = {j: 0.0 for j in joint_names}
    across = {j: 0.0 for j in joint_names}
    zero = np.zeros(model.nv)
    for row in np.atleast_2d(values):
        tau = pin.rnea(model, data, joint_configuration(model, qmap, row), zero, zero)
        for j, jid in zip(joint_names, ids):
            if axes[j] is None:
                continue
            along[j] = max(along[j], abs(float(tau[model.joints[jid].idx_v])))
            # the moment the joint transmits, about its placement origin (as robocal.model.joint_tilt takes it)
            motion = model.jointPlacements[jid].inverse() * data.liMi[jid]
            moment = motion.act(data.f[jid]).angular
            a = axes[j][0]
            across[j] = max(across[j], float(np.linalg.norm(moment - moment.dot(a) * a)))
    effort = {}
    for j, jid in zip(joint_names, ids):
        e = float(model.effortLimit[model.joints[jid].idx_v]) if model.joints[jid].nv == 1 else 0.0
        effort[j] = e if np.isfinite(e) and e > 0 else 0.0
    return JointLoads(along, across, effort)


def compliance_reference(loads: JointLoads, joint: str) -> tuple[float, str]:
    """(reference load, where it comes from) of a joint's compliance scale: its effort limit, unless the
    URDF states none or one below the gravity load the joint carries in the data (then that load)."""
    effort, carried = loads.effort.get(joint, 0.0), loads.along.get(joint, 0.0)
    if effort > 0 and effort >= carried:
        return effort, "effort limit"
    return carried, "largest gravity load in the data"


@dataclass
class PhysicalScales:
    """Per parameter name: its physical scale, the standard error below which it counts as determined, and
    (for the load and transmission kinds) what the scale was derived from, in words."""

    size: float
    scale: dict[str, float]
    determined: dict[str, float]
    basis: dict[str, str] = field(default_factory=dict)
    family: dict[str, str] = field(default_factory=dict)   # length | angle | relative | set-up: what the scale
                                                           # derives from (the default prior's strength is per family)

    def families(self, names) -> list[str]:
        return [self.family.get(n, "set-up") for n in names]

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
    loads = joint_loads(robot, joints, problem.values) if needs_load else JointLoads({}, {}, {})
    scale, det, basis, family = {}, {}, {}, {}
    measured = measured_frames(problem)
    # set-up quantities with a physical scale of their own (a camera's intrinsics): the residual says it
    declared = {n: v for r in problem.residuals for n, v in r.aux_scales().items()}
    length = length_fraction * size
    for p in params:
        if p.name in declared:
            scale[p.name], det[p.name] = declared[p.name]
            family[p.name] = "set-up"
            continue
        if is_registration(p, measured):
            if p.unit in ("m", "rad"):
                det[p.name] = det_length if p.unit == "m" else det_angle      # determinable, never out of scale
            continue
        if p.kind not in ROBOT_KINDS:
            continue
        ref, ref_det = (length, det_length) if is_length(p) else (angle_scale, det_angle)
        if p.kind in ("joint_compliance", "joint_tilt"):
            if p.kind == "joint_compliance":
                load, source = compliance_reference(loads, p.target)
            else:
                load, source = loads.across.get(p.target, 0.0), "largest gravity moment across the axis in the data"
            if load < MIN_LOAD:
                continue          # no load: the data cannot see it and no scale applies
            unit = "N" if is_length(p) else "N m"
            # a compliance of this size deflects the joint by the length / angle scale at the reference load
            scale[p.name], det[p.name] = ref / load, ref_det / load
            basis[p.name] = (f"{ref * 1e3:.3g} {'mm' if is_length(p) else 'mrad'} at {load:.3g} {unit} "
                             f"({source})")
        elif p.kind == "joint_backlash":      # the play, twice the half-play b, within the length / angle scale
            scale[p.name], det[p.name] = ref / 2.0, ref_det
        elif p.kind == "transmission":
            if p.name.endswith(".hand") or p.value == 0.0:
                continue                      # a discrete sign; a ratio of zero has no relative scale
            scale[p.name], det[p.name] = length_fraction * abs(p.value), DETERMINED_RELATIVE * abs(p.value)
            basis[p.name] = f"{length_fraction:.0%} of its nominal value {p.value:.6g}"
            family[p.name] = "relative"
            continue
        else:
            scale[p.name], det[p.name] = ref, ref_det
        family[p.name] = "length" if is_length(p) else "angle"
    return PhysicalScales(size, scale, det, basis, family)


def unit_label(p: Parameter | str) -> tuple[float, str]:
    """Report scale and unit of a parameter (or of a unit): mm for lengths, mrad for angles, else SI."""
    unit = p if isinstance(p, str) else p.unit
    return {"m": (1e3, "mm"), "rad": (1e3, "mrad"), "rad/(N m)": (1e3, "mrad/(N m)"),
            "m/N": (1e3, "mm/N")}.get(unit, (1.0, unit))
