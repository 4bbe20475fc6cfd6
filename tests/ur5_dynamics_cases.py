"""A simulated UR5 joint log (every joint recorded, no gear ratio, irregular time steps) written as the
three CSV files and the config `robocal identify` reads; shared by the dynamics tests on a robot other than
the TIAGo."""
import numpy as np
import pinocchio as pin
import yaml

from robocal import load_example
from robocal.dynamics.motor_simulation import perturbed_model
from robocal.dynamics.reduced_model import reduced_model
from tiago_dynamics_cases import trajectory

COULOMB, VISCOUS, OFFSET = 1.0, 2.0, 0.3          # N m, N m s/rad, N m: the same on every joint
EFFORT_NOISE, POSITION_NOISE = 0.05, 1e-4          # N m, rad


def write_ur5_log(folder, rows=6000, seed=0, spring=None, coulomb_pos_neg=None, delay=None, candidates=(),
                  viscous_pos_neg=None, offset=OFFSET, terms=("coulomb", "viscous", "offset"), robot_seed=None):
    """The log, its config and the truth. Optional truth terms, per joint (arrays of 6): spring (N m/rad, torque
    K q), coulomb_pos_neg ((6,), (6,): Fc+ and Fc- replacing the symmetric COULOMB), delay (s: the effort at t
    is the torque at t - delay); candidates: the config's model.candidate_terms."""
    robot = load_example("ur5")
    joints = robot.joint_names
    model = reduced_model(robot.urdf_path, joints)
    rng = np.random.default_rng(seed)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.0077, 0.0123, rows - 1))])
    q, v, a = trajectory(t, model, seed + 1)
    truth = perturbed_model(model, seed + 2 if robot_seed is None else robot_seed)     # robot_seed: the same robot
    data = truth.createData()
    tau = np.array([pin.rnea(truth, data, q[k], v[k], a[k]) for k in range(rows)])
    train, validate = (2.0, 0.75 * t[-1]), (0.75 * t[-1], t[-1])
    width = 0.05 * np.sqrt(np.mean(v[(t >= train[0]) & (t < train[1])] ** 2, axis=0))   # the config's rule
    smooth = np.tanh(v / width)
    tau += COULOMB * smooth + VISCOUS * v + offset
    if spring is not None:
        tau += np.asarray(spring) * q
    if coulomb_pos_neg is not None:
        pos, neg = (np.asarray(x) for x in coulomb_pos_neg)
        tau += pos * np.maximum(smooth, 0) + neg * np.minimum(smooth, 0) - COULOMB * smooth
    if viscous_pos_neg is not None:
        pos, neg = (np.asarray(x) for x in viscous_pos_neg)
        tau += pos * np.maximum(v, 0) + neg * np.minimum(v, 0) - VISCOUS * v
    if delay is not None:
        tau = np.column_stack([np.interp(t - d, t, tau[:, j]) for j, d in enumerate(delay)])
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
              "model": {"terms": list(terms), "coulomb_width": 0.05,
                        "candidate_terms": list(candidates)}}
    path = folder / "identify.yaml"
    path.write_text(yaml.safe_dump(config))
    extra = np.tile([COULOMB, VISCOUS, offset], len(joints))
    return path, truth, extra
