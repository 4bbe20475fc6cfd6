"""Write stewart_poses.csv (and its truth, stewart_poses_truth.json) for stewart_calibrate.yaml.

The true machine is the MJCF's nominal one with N(0, 1 mm) on each of its 42 parameters (base joints N, platform
joints T, strut offsets: docs/stewart_calibration.md). At 60 random tool poses in the workspace (+-15 deg) the
struts read the true machine's closed-form inverse kinematics; a tracker measures the tool pose with N(0, 10 um)
and N(0, 10 urad) noise. `robocal simulate` cannot make these rows: random strut readings would not assemble.
Run:  OMP_NUM_THREADS=1 python examples/closed_loops/make_stewart_data.py
"""
import json
from pathlib import Path

import numpy as np
import pinocchio as pin

from robocal.io import write_csv
from robocal.model import load_mjcf
from robocal.systems.stewart import calibration as sc, modes as sm

HERE = Path(__file__).resolve().parent
SAMPLES, SEED, NOISE = 60, 7, 1e-5

robot = load_mjcf(HERE / "stewart_6_6.xml")
rng = np.random.default_rng(SEED)
truth = sc.stewart_parameters()
for p in truth:
    p.value = rng.normal(0.0, 1e-3)
tool = sm.Tool(0.2)
tips = sc.random_tips(SAMPLES, rng)
_, R = sc.random_orientations(SAMPLES, rng)
poses = sc.tip_to_platform(tips, R, tool)
struts = sc.struts(sc.geometry(robot, truth), poses)
measured = [M * pin.SE3(np.eye(3), tool.tip) * pin.exp6(pin.Motion(rng.normal(0.0, NOISE, 6))) for M in poses]
columns = {f"leg{j + 1}_slide": struts[:, j] for j in range(6)}
xyzquat = np.array([pin.SE3ToXYZQUAT(M) for M in measured])
columns.update({name: xyzquat[:, k] for k, name in enumerate(["x", "y", "z", "qx", "qy", "qz", "qw"])})
write_csv(HERE / "stewart_poses.csv", columns)
(HERE / "stewart_poses_truth.json").write_text(json.dumps({"seed": SEED, "noise": NOISE,
                                                           "parameters": {p.name: p.value for p in truth}},
                                                          indent=1) + "\n")
print(f"wrote {HERE / 'stewart_poses.csv'} ({SAMPLES} rows) and its truth")
