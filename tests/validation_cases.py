"""Synthetic truth for the validation tests: a UR5 seen by a tracker at one point on its flange, written as a
robocal config + CSV so that the commands run exactly as a user would run them."""
import numpy as np
import yaml

from robocal import load_example
from robocal.design.simulate import perturb, random_configurations
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters

SIGMA = 5e-5          # m, tracker noise per axis
JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint"]


def truth_params(robot, rng, compliance=None, geometric=True, offsets=None, errors=(5e-4, 5e-4)):
    """errors: the placement errors' bounds (m, rad); by default half a millimetre / milliradian."""
    params = robot_parameters(robot, JOINTS, "full", base=True, compliance=list(compliance or {}))
    if geometric:   # placement errors: the full model is needed
        params = perturb(params, rng, *errors)
    for j, c in (compliance or {}).items():
        params[f"{j}.compliance"].value = c
    for j, o in (offsets or {}).items():
        params[f"{j}.offset"].value = o
    return params


def write_case(folder, rng, n=40, compliance=None, spread=None, parameters=None, groups=None, geometric=True,
               offsets=None, errors=(5e-4, 5e-4)):
    """config.yaml + data.csv of a simulated calibration; returns (config path, truth ParameterSet, values).
    offsets: true joint offsets (rad) set after the random placement errors (bounded by `errors`: m, rad)."""
    robot = load_example("ur5")
    truth = truth_params(robot, rng, compliance, geometric, offsets, errors)
    values = random_configurations(robot, JOINTS, n, rng)
    if spread is not None:       # shrink some joints' ranges: weakly seen directions
        for k, s in spread.items():
            values[:, JOINTS.index(k)] = values[0, JOINTS.index(k)] + s * rng.uniform(-1, 1, n)
    ms = ModelState(robot, truth, JOINTS)
    pts = np.array([ms.sample(v).pose("tool0").translation for v in values]) + rng.normal(0, SIGMA, (n, 3))
    cols = {**{j: values[:, i] for i, j in enumerate(JOINTS)}, "x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2]}
    if groups is not None:
        cols["session"] = groups
    lines = [",".join(cols)] + [",".join(repr(float(c[i])) if k != "session" else str(c[i])
                                         for k, c in cols.items()) for i in range(n)]
    (folder / "data.csv").write_text("\n".join(lines) + "\n")
    config = {"robot": {"example": "ur5"}, "data": {"csv": "data.csv", "joints": JOINTS},
              "parameters": {"preset": "full", "base": True, **(parameters or {})},
              "measurements": [{"type": "point", "name": "tracker", "frame": "tool0", "columns": ["x", "y", "z"],
                                "sigma": SIGMA}],
              "output": {"dir": "out", "report": False}}
    (folder / "config.yaml").write_text(yaml.safe_dump(config))
    return folder / "config.yaml", truth, values


COMPLIANT = ("shoulder_lift_joint", "elbow_joint")
# the second session's tracker: 0.3 m and 0.2 rad away from the first's
BASES = (np.zeros(6), np.array([0.3, -0.2, 0.1, 0.2, -0.1, 0.15]))


def write_sessions(folder, c, n=36):
    """Two sessions of one UR5 (placement errors of 0.5 mm / 0.5 mrad; shoulder and elbow compliance c) seen by
    a tracker at one flange point, 50 um noise, the tracker placed per BASES. Returns the config path."""
    rng = np.random.default_rng(11)
    robot = load_example("ur5")
    truth = truth_params(robot, rng, compliance={j: c for j in COMPLIANT})
    for k, base in enumerate(BASES):
        for comp, v in zip(("tx", "ty", "tz", "rx", "ry", "rz"), base):
            truth[f"base.{comp}"].value = v
        values = random_configurations(robot, JOINTS, n, rng)
        ms = ModelState(robot, truth, JOINTS)
        pts = np.array([ms.sample(v).pose("tool0").translation for v in values]) + rng.normal(0, SIGMA, (n, 3))
        rows = [",".join(JOINTS + ["x", "y", "z"])] + [",".join(repr(float(x)) for x in list(v) + list(p))
                                                        for v, p in zip(values, pts)]
        (folder / f"session{k + 1}.csv").write_text("\n".join(rows) + "\n")
    cfg = folder / "config.yaml"
    cfg.write_text(yaml.safe_dump({
        "robot": {"example": "ur5"}, "data": {"csv": "session1.csv", "joints": JOINTS},
        "parameters": {"preset": "full", "base": True, "compliance": list(COMPLIANT)},
        "measurements": [{"type": "point", "name": "tracker", "frame": "tool0", "columns": ["x", "y", "z"],
                          "sigma": SIGMA}]}))
    return cfg
