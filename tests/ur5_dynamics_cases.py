"""A simulated UR5 joint log (every joint recorded, no gear ratio, irregular time steps) written as the
three CSV files and the config `robocal identify` reads; shared by the dynamics tests on a robot other than
the TIAGo."""
import numpy as np
import pinocchio as pin
import yaml

from robocal import load_example
from robocal.dynamics.reduced_model import reduced_model
from tiago_dynamics_cases import trajectory, truth_model

COULOMB, VISCOUS, OFFSET = 1.0, 2.0, 0.3          # N m, N m s/rad, N m: the same on every joint
EFFORT_NOISE, POSITION_NOISE = 0.05, 1e-4          # N m, rad


def write_ur5_log(folder, rows=6000, seed=0):
    robot = load_example("ur5")
    joints = robot.joint_names
    model = reduced_model(robot.urdf_path, joints)
    rng = np.random.default_rng(seed)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.0077, 0.0123, rows - 1))])
    q, v, a = trajectory(t, model, seed + 1)
    truth = truth_model(model, seed + 2)
    data = truth.createData()
    tau = np.array([pin.rnea(truth, data, q[k], v[k], a[k]) for k in range(rows)])
    train, validate = (2.0, 0.75 * t[-1]), (0.75 * t[-1], t[-1])
    width = 0.05 * np.sqrt(np.mean(v[(t >= train[0]) & (t < train[1])] ** 2, axis=0))   # the config's rule
    tau += COULOMB * np.tanh(v / width) + VISCOUS * v + OFFSET
    logged = {"position": q + rng.normal(0.0, POSITION_NOISE, q.shape), "velocity": v,
              "effort": tau + rng.normal(0.0, EFFORT_NOISE, tau.shape)}
    for kind, values in logged.items():
        np.savetxt(folder / f"{kind}.csv", np.column_stack([t, values]), delimiter=",", comments="", fmt="%.17g",
                   header="t," + ",".join(f"- {j}_{kind}" for j in joints))
    config = {"robot": {"urdf": str(robot.urdf_path), "joints": joints},
              "data": {"position": "position.csv", "velocity": "velocity.csv", "effort": "effort.csv",
                       "time_column": "t"},
              "effort": {"recorded": joints, "gear_ratio": {j: 1 for j in joints},
                         "motor_constant": {j: 1 for j in joints}},
              "signal": {"cutoff_hz": "auto", "decimate": "auto", "velocity_source": "differentiated"},
              "windows": {"train": [float(x) for x in train], "validate": [float(x) for x in validate]},
              "model": {"terms": ["coulomb", "viscous", "offset"], "coulomb_width": 0.05}}
    path = folder / "identify.yaml"
    path.write_text(yaml.safe_dump(config))
    extra = np.tile([COULOMB, VISCOUS, OFFSET], len(joints))
    return path, truth, extra
