"""Simulated sessions of a robot with effects the ladder does and does not model, for benchmarks/selection_study.py.

A simulated robot (`SimRobot`) is a URDF, its read joints, the tool frame carrying a rigid body of four points,
and a plan of postures with a visiting order. `draw_truth` draws, per seed, the geometric errors (every joint's
offset and 6D placement error), joint compliance and backlash on some joints (modelled by the ladder's upper
rungs), and two effects no rung models: link bending (the distal chain sags along gravity in proportion to the
gravity moment the link carries) and an encoder's cyclic error (q_link = q_read + a sin(2 q_read + phi)).
`write_session` writes one session as the real TIAGo files are written (x1..z4, the joints, t_start_robot),
with its own tracker placement (a per-session base frame), a small drift of every joint zero (a day-to-day
change no model carries over) and marker noise.
Every effect is evaluated by robocal's own model (ModelState with the true ParameterSet) except the two
unmodelled ones, added here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import yaml

from robocal.estimation import term_errors
from robocal.model.kinematics import ModelState
from robocal.workflows import setup_for_data

NOISE = 2e-4            # m per axis: marker noise (the TIAGo data README: about 0.2 mm per plateau)
STATED_SIGMA = 5e-4     # m: the sigma the configs state (as the shipped TIAGo configs)
DRIFT = 5e-4            # rad (m): per-session change of every joint zero
LABELS = ["BL", "BR", "TR", "TL"]


@dataclass
class SimRobot:
    name: str
    robot_cfg: dict              # config `robot` section
    joints: list[str]
    tool: str
    points: np.ndarray           # (4, 3) the body's points in the tool frame (m)
    compliant: list[str]         # joints given a compliance in the truth
    play: list[str]              # joints given backlash
    bending: str                 # joint whose link bends (its distal chain sags)
    eccentric: list[str]         # joints with a cyclic encoder error
    tilt: list[str]              # joints the ladder's tilt rung frees
    base0: np.ndarray            # (6,) the first session's tracker placement (base parameters)


def configs(sim: SimRobot, folder) -> dict:
    """{"point": path, "hand": path}: the configs of the two measurement choices, on a placeholder CSV."""
    common = {"robot": sim.robot_cfg, "data": {"csv": "placeholder.csv", "joints": sim.joints,
                                                "approach": {"from": "order", "sort_by": "t_start_robot"}},
              "parameters": {"preset": "full", "base": True}, "output": {"dir": "out", "report": False}}
    point = {"type": "point", "name": "BL", "frame": sim.tool, "point_unknown": True, "columns": ["x1", "y1", "z1"],
             "sigma": STATED_SIGMA}
    hand = {"type": "rigid_points", "name": "hand", "frame": sim.tool, "labels": LABELS,
            "points": [[0.0, 0.0, 0.0]] * 4, "points_unknown": True,
            "columns": [f"{a}{i}" for i in range(1, 5) for a in "xyz"], "sigma": STATED_SIGMA}
    out = {}
    for key, block in (("point", point), ("hand", hand)):
        path = folder / f"{sim.name}_{key}.yaml"
        path.write_text(yaml.safe_dump({**common, "measurements": [block]}, sort_keys=False))
        out[key] = path
    return out


def truth_setup(sim: SimRobot, config, csv):
    return setup_for_data(config, csv, {"preset": "full", "compliance": sim.compliant, "backlash": sim.play,
                                        "tilt": False})


def draw_truth(sim: SimRobot, config, csv, rng: np.random.Generator, scenario: str) -> dict:
    """{parameter name: value} of the robot (no base) and the unmodelled effects' sizes, for a scenario:
    'geometric' (placements and offsets), 'compliance' (+ compliance), 'all' (+ backlash, bending, eccentricity)."""
    s = truth_setup(sim, config, csv)
    values = {}
    for p in s.problem.params:
        if p.kind == "joint_placement":
            values[p.name] = rng.normal(0, 1e-3 if p.name[-2] == "t" else 2e-3)
        elif p.kind == "joint_offset":
            values[p.name] = rng.normal(0, 5e-3)
        elif p.kind == "auxiliary":
            values[p.name] = float(sim.points[LABELS.index(p.name.split(".")[1]), "xyz".index(p.name[-1])])
    from robocal.estimation.physical_scale import joint_loads
    loads = joint_loads(s.robot, sim.joints, s.problem.values)
    if scenario in ("compliance", "all"):
        for j in sim.compliant:      # 3-10 mrad of sag at the joint's largest gravity moment
            values[f"{j}.compliance"] = rng.uniform(3e-3, 10e-3) / max(loads.along[j], 1e-3)
    effects = {"bending": 0.0, "eccentricity": {}}
    if scenario == "all":
        for j in sim.play:
            values[f"{j}.backlash"] = -rng.uniform(3e-3, 8e-3)
        effects["bending"] = rng.uniform(2e-3, 4e-3) / max(loads.along[sim.bending], 1e-3)   # m per N m
        effects["eccentricity"] = {j: (rng.uniform(2e-3, 4e-3), rng.uniform(-np.pi, np.pi)) for j in sim.eccentric}
    return {"values": values, "effects": effects}


def base_for_session(sim: SimRobot, rng: np.random.Generator, moved: bool) -> np.ndarray:
    """The tracker placement of a session: the first session's, or moved by up to 0.2 m / 0.2 rad."""
    if not moved:
        return sim.base0.copy()
    return sim.base0 + np.concatenate([rng.uniform(-0.2, 0.2, 3), rng.uniform(-0.2, 0.2, 3)])


def _moments(robot, joints, values, joint: str) -> np.ndarray:
    """Gravity moment magnitude (N m) the link after `joint` carries, per posture (nominal model)."""
    model = robot.model
    data = model.createData()
    jid = robot.joint_id(joint)
    idx = [model.joints[robot.joint_id(j)].idx_q for j in joints]
    out = np.zeros(len(values))
    for k, row in enumerate(values):
        q = pin.neutral(model)
        q[idx] = row
        pin.centerOfMass(model, data, q, False)
        pin.forwardKinematics(model, data, q)
        arm = data.com[jid] - data.oMi[jid].translation
        out[k] = np.linalg.norm(np.cross(arm, data.mass[jid] * model.gravity.linear))
    return out


def write_session(sim: SimRobot, config, path, readings: np.ndarray, times: np.ndarray, truth: dict,
                  base: np.ndarray, rng: np.random.Generator) -> None:
    """Write one session's CSV: the true robot at `readings` seen from the tracker at `base`, plus noise."""
    ecc = truth["effects"]["eccentricity"]
    # every session: the joint zeros drift a little (re-homing, temperature), which no model carries over
    true_q = readings + rng.normal(0, DRIFT, readings.shape[1]) * (truth["values"] != {})
    for j, (a, phi) in ecc.items():
        k = sim.joints.index(j)
        true_q[:, k] += a * np.sin(2 * readings[:, k] + phi)     # two cycles a turn: no offset absorbs it
    _write(path, sim, true_q, times, np.zeros((len(readings), 12)))
    s = truth_setup(sim, config, path)
    params = s.problem.params
    for name, v in truth["values"].items():
        if name in params:
            params[name].value = v
    for c, v in zip(("tx", "ty", "tz", "rx", "ry", "rz"), base):
        params[f"base.{c}"].value = v
    pts = term_errors(s.problem)["hand"].raw.reshape(len(readings), 4, 3)    # prediction - 0
    if truth["effects"]["bending"]:
        sag = truth["effects"]["bending"] * _moments(s.robot, sim.joints, readings, sim.bending)
        R = ModelState(s.robot, params, sim.joints).base.rotation        # robot root -> tracker
        g = s.robot.model.gravity.linear / np.linalg.norm(s.robot.model.gravity.linear)
        pts += (sag[:, None] * (R @ g)[None, :])[:, None, :]
    pts += rng.normal(0, NOISE, pts.shape)
    _write(path, sim, readings, times, pts.reshape(len(readings), 12))


def _write(path, sim: SimRobot, readings, times, pts) -> None:
    head = [f"{a}{i}" for i in range(1, 5) for a in "xyz"] + sim.joints + ["t_start_robot"]
    rows = [",".join(head)] + [",".join(repr(float(v)) for v in list(p) + list(q) + [t])
                               for p, q, t in zip(pts, readings, times)]
    path.write_text("\n".join(rows) + "\n")
