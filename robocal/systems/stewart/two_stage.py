"""Two-stage calibration for large initial errors (docs/stewart_calibration.md).

Stage 1 fits the inverse-kinematics residual (StrutIKResidual: closed-form strut length at the
measured full pose minus the reading) on an OPEN copy of the Stewart model whose platform hangs on six
1-dof joints (X, Y, Z translations, then rotations about x, y, z: R = Rx(A) Ry(B) Rz(C)) read from
the measured poses. It needs no loop assembly, so it stays defined with parameters hundreds of
millimetres off, where the forward-kinematics fit cannot even assemble the machine. Stage 2 is the
ordinary forward-kinematics fit (any mix of modes) started from stage 1's parameters.

Both stages use the same parameter names, so stage 1's values are copied over by name.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.errors import InputError
from robocal.model.kinematics import ModelState
from robocal.model.loops_urdf import read_loops
from robocal.model.parameters import ParameterSet
from robocal.estimation.problem import Problem
from robocal.residuals.strut_ik import StrutIKResidual
from robocal.estimation.result import CalibrationResult
from robocal.model.robot import Robot
from robocal.systems.stewart.mechanism import configuration_from_pose, geometry_from_model
from robocal.systems.stewart.modes import Tool, angles, numeric_rows, rotation

POSE_JOINTS = ("pose_x", "pose_y", "pose_z", "pose_a", "pose_b", "pose_c")
FLOATING = "platform_float"


def open_model(robot) -> Robot:
    """The Stewart robot with its floating platform replaced by six read 1-dof joints and no loops
    (the closure anchor frames `leg{j}_top.link1/.link2` are kept)."""
    tree = etree.fromstring(robot.urdf_text.encode("utf-8"))
    joint = next((j for j in tree.findall("joint") if j.get("name") == FLOATING), None)
    if joint is None:
        raise InputError(f"no floating joint '{FLOATING}': not a robocal Stewart URDF", source=str(robot.urdf_path),
                         field=FLOATING)
    parent, child = joint.find("parent").get("link"), joint.find("child").get("link")
    index = list(tree).index(joint)
    tree.remove(joint)
    links = [parent] + [f"pose_link_{k}" for k in range(5)] + [child]
    limit = '<limit lower="-3.2" upper="3.2" effort="0" velocity="0"/>'
    new = [f'<link name="{name}"/>' for name in links[1:-1]]
    for k, name in enumerate(POSE_JOINTS):
        kind = "prismatic" if k < 3 else "revolute"
        axis = " ".join("1" if i == k % 3 else "0" for i in range(3))
        new.append(f'<joint name="{name}" type="{kind}"><parent link="{links[k]}"/><child link="{links[k + 1]}"/>'
                   f'<origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="{axis}"/>{limit}</joint>')
    for k, text in enumerate(new):
        tree.insert(index + k, etree.fromstring(text))
    text = etree.tostring(tree, encoding="unicode")
    out = Robot(model=pin.buildModelFromXML(text), urdf_path=robot.urdf_path, urdf_text=text,
                name=f"{robot.name}_open", base_placement=robot.base_placement)
    read_loops(out, tree)      # adds the anchor frames; the open model closes no loop
    out.loops = None
    return out


def ik_readings(tool_rows, struts, tool: Tool, convention: str = "xyz_intrinsic",
                source: str = "pose rows") -> np.ndarray:
    """(K, 12) readings of the open model: platform X Y Z A B C (Rx Ry Rz) from measured tool-tip
    rows (K, 6) X Y Z A B C (in `convention`), then the six strut coordinates."""
    rows = numeric_rows(tool_rows, 6, source)
    s = numeric_rows(struts, 6, "struts")
    if len(s) != len(rows):
        raise InputError(f"{len(rows)} pose rows but {len(s)} strut rows", source=source)
    out = np.zeros((len(rows), 12))
    for k, r in enumerate(rows):
        R = rotation(r[3:], convention)
        out[k, :3] = r[:3] - R @ tool.tip
        out[k, 3:6] = angles(R, "xyz_intrinsic")
    out[:, 6:] = s
    return out


def ik_problem(robot, params: ParameterSet, tool_rows, struts, tool: Tool, convention: str = "xyz_intrinsic",
               sigma: float = 1e-5) -> Problem:
    """Stage-1 problem: StrutIKResidual on the open model, one term per full pose."""
    open_robot = open_model(robot)
    values = ik_readings(tool_rows, struts, tool, convention)
    legs = [(f"leg{j}_u1", f"leg{j}_top.link2", f"leg{j}_top.link1") for j in range(1, 7)]
    joints = list(POSE_JOINTS) + list(robot.loops.actuated)
    return Problem(open_robot, params, joints, values, [StrutIKResidual("strut_ik", np.arange(len(values)), legs,
                                                                        sigma=sigma)])


def ik_stage(robot, params: ParameterSet, tool_rows, struts, tool: Tool, convention: str = "xyz_intrinsic",
             sigma: float = 1e-5, options: CalibrationOptions | None = None) -> CalibrationResult:
    """Fit `params` (in place: values only; which parameters vary is left as it was) to full poses by
    the IK residual. Returns stage 1's result (parameters on a copy)."""
    work = params.copy()
    result = calibrate(ik_problem(robot, work, tool_rows, struts, tool, convention, sigma), options,
                       source="inverse-kinematics stage")
    for p in work:
        if p.kind != "auxiliary" and p.name in params:
            params[p.name].value = p.value
    return result


def calibrate_two_stage(problem: Problem, pose_samples, tool_rows, tool: Tool, convention: str = "xyz_intrinsic",
                        sigma: float = 1e-5, options: CalibrationOptions | None = None
                        ) -> tuple[CalibrationResult, CalibrationResult]:
    """Stage 1 on the full poses `tool_rows` measured at samples `pose_samples` of `problem`, then the
    forward-kinematics fit of `problem` from there. Returns (stage 1 result, final result)."""
    idx = np.asarray(pose_samples, dtype=int).reshape(-1)
    first = ik_stage(problem.robot, problem.params, tool_rows, problem.values[idx], tool, convention, sigma, options)
    warm_start(problem, idx, tool_rows, tool, convention)
    return first, calibrate(problem, options)


def warm_start(problem: Problem, pose_samples, tool_rows, tool: Tool, convention: str = "xyz_intrinsic") -> None:
    """Seed the loop assembly of `problem`'s pose samples with the closed-form configuration at the
    measured poses for the current parameters (far from the nominal machine, Newton from the home
    pose may not reach the assembly; from the measured pose it starts next to it)."""
    problem.warm_starts.clear()           # the old assemblies belong to the old parameters
    ms = ModelState(problem.robot, problem.params, problem.joint_names)
    geo = geometry_from_model(problem.robot, ms.model)
    rows = numeric_rows(tool_rows, 6, "pose rows")
    for i, r in zip(np.asarray(pose_samples, dtype=int).reshape(-1), rows):
        R = rotation(r[3:], convention)
        pose = pin.SE3(R, r[:3] - R @ tool.tip)
        problem.warm_starts[int(i)] = configuration_from_pose(problem.robot, geo, pose, ms.model)
