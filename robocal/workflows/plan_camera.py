"""`robocal plan` for a config whose measurement block is a camera: candidates that keep the target in view.

The candidates are viewpoints of the target reached by inverse kinematics on the nominal robot
(robocal.design.camera_candidates: every corner inside the image with a margin, the target facing the camera),
`plan.candidates.count` of them; the design problem sees every corner at every candidate
(robocal.design.camera_design_problem) with the config's preset, parameter overrides and intrinsics (free and
priors as the block says). Where the part not on the robot is comes from the block's `world_pose`; the frame on
the robot is the robot's own (robot.frames) or, when it has none, `attached_to` itself. IK starts from the
data's first row when the data file exists, else from the middle of the joint ranges.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.design.camera_poses import camera_candidates, camera_design_problem
from robocal.design.candidates import CandidateFilter
from robocal.errors import InputError
from robocal.io.camera_target import target_from_dict
from robocal.io.tables import read_csv
from robocal.residuals.camera_model import camera_spec_from_dict
from robocal.workflows.config_sections import apply_parameter_overrides, joint_values
from robocal.workflows.config_types import CalibrationConfig, MeasurementConfig, PlanConfig


def camera_block(config: CalibrationConfig) -> MeasurementConfig | None:
    """The config's camera block (None without one); refused beside other blocks."""
    cams = [m for m in config.measurements if m.camera is not None]
    if cams and len(config.measurements) > 1:
        raise InputError("robocal plan takes a camera block as the only measurement block; plan mixes from Python "
                         "(robocal.design.selection)", source=config.source, field=f"{cams[0].path}.type")
    return cams[0] if cams else None


def seed_reading(config: CalibrationConfig, robot, joint_cols: dict[str, str]) -> np.ndarray:
    """Where IK starts: the data's first row when the file exists, else the middle of the joint ranges."""
    data = config.data.csv
    if data is not None and data.is_file():
        return joint_values(robot, read_csv(data), joint_cols, [0], config.data.joint_units)[0]
    lo, hi = robot.limits(list(joint_cols))
    return np.where(np.isfinite(lo) & np.isfinite(hi), (lo + hi) / 2, 0.0)


def camera_plan_problem(config: CalibrationConfig, plan: PlanConfig, m: MeasurementConfig, robot,
                        joint_cols: dict[str, str], rng: np.random.Generator):
    """(the screening, the candidate readings, the design problem) of a camera block (module docstring)."""
    cam, source = m.camera, config.source
    if cam.world_pose is None:
        where = "target" if cam.mount == "eye_in_hand" else "camera"
        raise InputError(f"robocal plan needs where the {where} is in the world (world_pose: {{xyz, rpy}}, m and rad)",
                         source=source, field=f"{m.path}.world_pose")
    noise = m.sigma if plan.noise is None else plan.noise
    if isinstance(noise, tuple):
        raise InputError("a camera's noise is one number of pixels", source=source, field="plan.noise")
    target = target_from_dict(cam.target, source, f"{m.path}.target")
    spec = camera_spec_from_dict(cam.camera, source, f"{m.path}.camera")
    if not robot.model.existFrame(m.frame):
        robot.add_frame(m.frame, cam.attached_to, pin.SE3.Identity())
    fixed = pin.SE3(pin.rpy.rpyToMatrix(*np.asarray(cam.world_pose.rpy, float)), np.asarray(cam.world_pose.xyz, float))
    joint_names = list(joint_cols)
    found = camera_candidates(robot, joint_names, m.frame, cam.mount, fixed, target, spec.model, spec.intrinsics,
                              plan.candidates.count, rng, seed_reading(config, robot, joint_cols))
    if len(found.values) < 2:
        raise InputError(f"{len(found.values)} candidate poses keep the whole target in view ({found.dropped}): check "
                         "world_pose, the frame's placement and the intrinsics", source=source, field=f"{m.path}.world_pose")
    joints = list(config.parameters.joints) if config.parameters.joints is not None else None
    try:
        problem = camera_design_problem(robot, joint_names, found.values, m.frame, cam.mount, fixed, target,
                                        spec.model, spec.intrinsics, config.parameters.preset, float(noise),
                                        spec.free, m.name, spec.prior, joints)
    except InputError as exc:
        raise InputError(exc.reason, source=source, field="parameters") from None
    apply_parameter_overrides(config.parameters, problem.params, source)
    return CandidateFilter(np.arange(len(found.values)), dict(found.dropped)), found.values, problem
