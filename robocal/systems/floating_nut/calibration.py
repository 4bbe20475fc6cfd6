"""Calibrating a rod-end-floating hexapod through the generic layer (docs/floating_nut_hexapod.md).

The machine's URDF (mechanisms/floating_nut_urdf) is a closed chain whose stroke joints are driven
through `<screw_transmission>` rows (robocal.model.joint_relations): the encoder reading u is the command
length, and q_stroke + sigma L/2pi q_roll = (L/L0) u. Its parameters map onto generic kinds:

  base Hooke centres b_i     joint_placement  leg{i}_hooke_base_1.tx/ty/tz
  platform Hooke centres m_i frame_placement  leg{i}_closure.link2.tx/ty/tz   (anchor on the platform)
  encoder zero per strut     joint_offset     leg{i}_stroke.offset            (acts through the screw row)
  screw lead per strut       transmission     leg{i}_screw.lead
  thread hand per strut      transmission     leg{i}_screw.hand               (+-1, fixed; choose_thread_hands)
  base Hooke axis a_i        joint_placement  leg{i}_hooke_base_1.rx/ry/rz    (rotating the base cross)
  platform Hooke axis c_i    frame_placement  leg{i}_closure.link1.rx/ry/rz   (rotating the weld to the platform)

A rotation of a Hooke frame about its own axis only shifts a passive joint's zero: the identifiability
analysis reports it as undetermined, and the axes are weakly determined in any case (they act through
L/2pi x roll, about 1.6 mm per rad for a 10 mm lead), so they are off by default (docs/floating_nut_hexapod.md).
"""
from __future__ import annotations

import copy

from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.model.loops import LoopSet
from robocal.model.parameters import Parameter, ParameterSet, offset_parameter, placement_parameters
from robocal.model.robot import Robot

LEGS = 6
XYZ = ("tx", "ty", "tz")
ROT = ("rx", "ry", "rz")


def floating_nut_parameters(robot: Robot, base_anchors: bool = True, platform_anchors: bool = True,
                            offsets: bool = True, leads: bool = True, hooke_axes: bool = False) -> ParameterSet:
    """The machine's calibration parameters, all at their nominal values (0 errors, URDF leads)."""
    ps = ParameterSet()
    screws = robot.loops is not None and any(r.kind == "screw" for r in robot.loops.relations)
    for i in range(1, LEGS + 1):
        if base_anchors:
            for p in placement_parameters("joint_placement", f"leg{i}_hooke_base_1", XYZ):
                ps.add(p)
        if platform_anchors:
            for p in placement_parameters("frame_placement", f"leg{i}_closure.link2", XYZ):
                ps.add(p)
    for i in range(1, LEGS + 1):
        if offsets:
            ps.add(offset_parameter(f"leg{i}_stroke", "m"))
        if leads:
            ps.add(transmission_parameter(robot, f"leg{i}_screw", "lead"))
        if screws:
            ps.add(transmission_parameter(robot, f"leg{i}_screw", "hand"))
    if hooke_axes:
        for i in range(1, LEGS + 1):
            for p in placement_parameters("joint_placement", f"leg{i}_hooke_base_1", ROT):
                ps.add(p)
            for p in placement_parameters("frame_placement", f"leg{i}_closure.link1", ROT):
                ps.add(p)
    return ps


def transmission_parameter(robot: Robot, relation: str, component: str) -> Parameter:
    """A `transmission` parameter at the URDF's value; the discrete hand is never varied."""
    rel = next((r for r in (robot.loops.relations if robot.loops else []) if r.name == relation), None)
    if rel is None:
        raise ValueError(f"robot '{robot.name}' has no joint relation '{relation}'")
    unit = {"lead": "m", "hand": "", "ratio": ""}[component]
    return Parameter(f"{relation}.{component}", "transmission", relation, 0, value=rel.value(component),
                     vary=component != "hand", unit=unit)


def uncompensated_robot(robot: Robot) -> Robot:
    """The same machine read as a classic 6-UPS: its screw rows dropped, so each encoder reading is taken
    as the effective strut length (what a tool without nut-roll compensation fits). Shares the model."""

    out = copy.copy(robot)
    L = robot.loops
    out.loops = LoopSet(robot.model, L.closures, L.actuated, [r for r in L.relations if r.kind != "screw"])
    return out


def choose_thread_hands(problem, options: CalibrationOptions | None = None, legs=range(1, LEGS + 1)):
    """Fit, flip each leg's thread hand in turn and keep a flip that lowers the fitted cost (docs/floating_nut_hexapod.md:
    sigma is discrete). Returns (result of the final fit, {relation: chosen sigma}); problem.params end at
    that fit."""
    start = problem.params.copy()
    best = calibrate(problem, options)
    best_params = problem.params.copy()
    for i in legs:
        name = f"leg{i}_screw.hand"
        trial = best_params.copy()
        for p in trial:                      # restart from the nominal values with one hand flipped
            if p.vary and p.tied_to is None:
                p.value = start[p.name].value
        trial[name].value = -trial[name].value
        problem.params = trial
        result = calibrate(problem, options)
        if result.solve.cost < best.solve.cost:
            best, best_params = result, trial.copy()
    problem.params = best_params
    return best, {p.target: int(p.value) for p in best_params if p.kind == "transmission" and p.name.endswith(".hand")}
