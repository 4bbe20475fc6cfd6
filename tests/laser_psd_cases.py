"""The seed-001 reference set-up (spec 6.3) shared by the laser/PSD tests."""
from functools import lru_cache
from pathlib import Path

import numpy as np

from robocal.model.kinematics import ModelState
from robocal.systems.laser_psd.calibration import LaserMount
from robocal.systems.laser_psd.plans import multi_fan, patent_fan, plan_configurations
from robocal.model.parameters import robot_parameters
from robocal.model.robot import load_urdf

URDF = Path(__file__).resolve().parents[1] / "urdf" / "abb_irb1600.urdf"
DELTA_TRUE = np.radians([0.3, -0.2, 0.25, -0.4, 0.3, 0.2])
TARGET = np.array([0.95, 0.10, 0.30])
DIRECTION = np.array([0.3, 0.0, -1.0]) / np.linalg.norm([0.3, 0.0, -1.0])
# Roll of the reference beam frame: puts the laser's offset from z6 across the patent fan's axis; with
# roll 0 it lies along that axis, every beam then shifts the same way under joint 6 and the fan cannot
# see joint 6 (condition number 6e7).
ROLL = np.radians(-90.0)
MOUNT = LaserMount([0.0, 0.04, 0.08], [0.0, 0.0, 1.0])


@lru_cache(maxsize=1)
def robot():
    return load_urdf(URDF)


def joints():
    return robot().joint_names


def truth(delta=DELTA_TRUE):
    params = robot_parameters(robot(), joints(), "offsets")
    for j, d in zip(joints(), delta):
        params[f"{j}.offset"].value = float(d)
    return params


def plans():
    return {"patent": patent_fan(), "three_fans": multi_fan()}


@lru_cache(maxsize=8)
def exact_readings(design: str, delta: tuple = tuple(DELTA_TRUE)) -> np.ndarray:
    """Readings at which the TRUE robot's beam passes exactly through the PSD centre (IK to 1e-12)."""
    return readings_for(MOUNT, plans()[design], np.array(delta))


def readings_for(mount, plan, delta=DELTA_TRUE, target=TARGET, direction=DIRECTION, roll=ROLL):
    ms = ModelState(robot(), truth(delta), joints())
    return plan_configurations(robot(), ms, joints(), mount, plan, target, direction, roll)
