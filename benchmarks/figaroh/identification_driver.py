"""FIGAROH side of the TIAGo dynamic-identification benchmark; runs with the FIGAROH virtual environment's
python (benchmarks/figaroh_env.py), never with robocal's.

    <venv>/bin/python identification_driver.py request.json

The request (JSON) names: config (tiago_identification.yaml beside this file), urdf, position / velocity /
effort (robocal's shipped CSVs, examples/tiago_dynamics/data/), train_rows [first, end) (the rows of
robocal's training window), validate [t0, t1] s, torque_scale per joint (gear ratio x motor constant; 1 for
a joint absent from it, whose effort is not fitted), result (where this script writes its JSON answer).
Steps, as FIGAROH's TIAGo example (thanhndv212/figaroh-examples,
examples/tiago/identification.py with utils/tiago_tools.py TiagoIdentification) runs them: a
BaseIdentification subclass loads the three CSVs; initialize(truncate=train_rows) filters (median 5, then
Butterworth 2 Hz, order 4, zero phase), differentiates positions twice, converts efforts, builds the
regressor; solve() eliminates zero columns, decimates by 10, finds the base parameters by double QR and
fits them by ordinary least squares. Timed: robot model to solve() returned.

Prediction on the validation window: FIGAROH's own held-out processing (the same filters on the whole
shipped log, no truncation) gives the kinematics; the torque of each recorded joint is the base regressor
of those samples times the base parameters, at every log row with t in `validate`.
"""
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pinocchio as pin
from pinocchio.robot_wrapper import RobotWrapper

from figaroh.identification.base_identification import BaseIdentification
from figaroh.tools.regressor import build_regressor_basic, build_regressor_reduced

GRAVITY = 9.81     # m/s^2, the example's value for the torso's carried weight


class TiagoLogIdentification(BaseIdentification):
    """The example's TiagoIdentification on robocal's shipped log: columns `- <joint>_<kind>` and `t`,
    velocity from the filtered positions, effort x gear ratio x motor constant (+ carried weight, torso)."""

    def __init__(self, robot, config_file, request):
        self.request = request
        super().__init__(robot, config_file)

    def load_trajectory_data(self, data_source=None):
        joints = self.identif_config["active_joints"]
        frames = {kind: pd.read_csv(self.request[kind]) for kind in ("position", "velocity", "effort")}
        return {"timestamps": frames["position"]["t"].to_numpy(float),
                "positions": frames["position"][[f"- {j}_position" for j in joints]].to_numpy(float),
                "velocities": None, "accelerations": None,       # from the filtered positions
                "torques": frames["effort"][[f"- {j}_effort" for j in joints]].to_numpy(float)}

    def process_torque_data(self, **kwargs):
        joints = self.identif_config["active_joints"]
        model, data = self.robot.model, self.robot.data
        pin.computeSubtreeMasses(model, data)
        scale = np.array([self.request["torque_scale"].get(j, 1.0) for j in joints])
        offset = np.array([GRAVITY * data.mass[model.getJointId(j)] if j == "torso_lift_joint" else 0.0
                           for j in joints])
        return self.raw_data["torques"] * scale + offset


def configure(ident) -> None:
    """What the example sets beside the yaml: joint ids and indices of the active joints."""
    ps = ident.identif_config
    ps["act_Jid"] = [ident.model.getJointId(j) for j in ps["active_joints"]]
    ps["act_J"] = [ident.model.joints[i] for i in ps["act_Jid"]]
    ps["act_idxq"] = [J.idx_q for J in ps["act_J"]]
    ps["act_idxv"] = [J.idx_v for J in ps["act_J"]]


def predict_window(ident, window) -> tuple[np.ndarray, dict]:
    """(log times in `window`, {fitted joint: predicted torque}) with FIGAROH's held-out processing."""
    ident._load_validation_data(None)          # the library's held-out path: whole log, same filters
    data = ident._val_processed_data
    t = np.asarray(data["timestamps"]).reshape(-1)
    rows = np.flatnonzero((t >= window[0]) & (t < window[1]))
    W = build_regressor_basic(ident.robot, data["positions"][rows], data["velocities"][rows],
                              data["accelerations"][rows], ident.identif_config)
    tau = build_regressor_reduced(W, ident._idx_eliminated)[:, ident._base_indices] @ ident.phi_base
    n = len(rows)
    by_joint = {}
    for name, v in zip(ident.identif_config["active_joints"], ident.identif_config["act_idxv"]):
        if name in ident.fit_joints():
            by_joint[name] = tau[v * n:(v + 1) * n].tolist()
    return t[rows], by_joint


def main(request_path: str) -> None:
    request = json.loads(Path(request_path).read_text())
    t0 = time.perf_counter()
    # model only: the URDF's meshes are not distributed, and FIGAROH's load_robot would load them
    robot = RobotWrapper(pin.buildModelFromUrdf(request["urdf"]))
    ident = TiagoLogIdentification(robot, request["config"], request)
    configure(ident)
    ident.initialize(truncate=tuple(request["train_rows"]))
    ident.solve(decimate=True, plotting=False, save_results=False, html_report=False, wls=False)
    seconds = time.perf_counter() - t0
    t_val, predicted = predict_window(ident, request["validate"])
    pin.computeSubtreeMasses(robot.model, robot.data)
    answer = {"identification_s": seconds, "base_parameters": len(ident.phi_base),
              "training_samples": int(ident.num_samples), "fit_rows": int(len(ident.tau_noised)),
              "torso_carried_mass_kg": float(robot.data.mass[robot.model.getJointId("torso_lift_joint")]),
              "condition": float(np.linalg.cond(ident.dynamic_regressor_base)),
              "t": t_val.tolist(), "predicted": predicted}
    Path(request["result"]).write_text(json.dumps(answer))


if __name__ == "__main__":
    main(sys.argv[1])
