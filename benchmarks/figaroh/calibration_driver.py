"""FIGAROH side of the TIAGo full-placement calibration benchmark; runs with the FIGAROH virtual
environment's python (benchmarks/figaroh_env.py), never with robocal's.

    <venv>/bin/python calibration_driver.py request.json

The request (JSON) names: mode ('fit': time solve_optimisation() alone; 'script': the whole driver, timed by
the caller from process start to files written), config (tiago_calibration.yaml beside this file), urdf,
training and validation (robocal's shipped mocap CSVs), workdir (converted CSVs and, in 'script' mode, the
results) and result (where this script writes its JSON answer). The steps follow FIGAROH's TIAGo example
(thanhndv212/figaroh-examples, examples/tiago/calibration.py and heldout_protocol.py): a BaseCalibration
subclass whose cost is the SE(3) log-map residual of the measured point, both frames estimated,
initialize(), then solve_optimisation() / solve(). RMSE: norm RMSE of the point's position error over the
postures (sqrt(mean |e|^2), mm), the data README's definition, computed with FIGAROH's calc_updated_fkm.
"""
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pinocchio as pin
from pinocchio.robot_wrapper import RobotWrapper

from figaroh.calibration.base_calibration import BaseCalibration
from figaroh.calibration.calibration_tools import calc_updated_fkm

JOINTS = ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)]
POINT = ["x1", "y1", "z1"]      # point BL, the only point FIGAROH's protocol uses


class TiagoMocapCalibration(BaseCalibration):
    """The example's TiagoCalibration: residual = SE(3) log map of the measured point (position only here).
    `calls` counts the objective evaluations, finite-difference Jacobian columns included."""

    calls = 0

    def cost_function(self, var):
        self.calls += 1
        estimated = calc_updated_fkm(self.model, self.data, var, self.q_measured, self.calib_config)
        return self._compute_logmap_residuals(self.PEE_measured, estimated)


def convert(source: str, target: Path) -> Path:
    """robocal's mocap CSV -> FIGAROH's input: columns x1, y1, z1 and one column per active joint."""
    frame = pd.read_csv(source)
    frame[POINT + JOINTS].to_csv(target, index=False)
    return target


def rmse_mm(calib, csv: Path, x) -> float:
    """Norm RMSE (mm) of BL at the postures of `csv` for FIGAROH's parameter vector x."""
    frame = pd.read_csv(csv)
    model = calib.model
    q = np.tile(calib.calib_config["q0"], (len(frame), 1))
    for j in JOINTS:
        q[:, model.joints[model.getJointId(j)].idx_q] = frame[j].to_numpy()
    config = dict(calib.calib_config, NbSample=len(frame))
    predicted = calc_updated_fkm(model, model.createData(), x, q, config).reshape(3, -1).T
    error = (predicted - frame[POINT].to_numpy()) * 1e3
    return float(np.sqrt(np.mean(np.sum(error ** 2, axis=1))))


def build(request: dict, training: Path) -> TiagoMocapCalibration:
    # model only: the URDF's meshes are not distributed, and FIGAROH's load_robot would load them
    robot = RobotWrapper(pin.buildModelFromUrdf(request["urdf"]))
    calib = TiagoMocapCalibration(robot, request["config"], del_list=[])
    calib.calib_config["data_file"] = str(training)
    calib._data_path = str(training)
    calib.calib_config["known_baseframe"] = False
    calib.calib_config["known_tipframe"] = False
    calib.initialize()
    return calib


def main(request_path: str) -> None:
    request = json.loads(Path(request_path).read_text())
    work = Path(request["workdir"])
    work.mkdir(parents=True, exist_ok=True)
    training = convert(request["training"], work / "training.csv")
    validation = convert(request["validation"], work / "validation.csv") if request["mode"] == "fit" else None
    t0 = time.perf_counter()
    calib = build(request, training)
    answer = {"mode": request["mode"], "build_initialize_s": time.perf_counter() - t0}
    if request["mode"] == "fit":
        t0, c0 = time.perf_counter(), time.process_time()
        result, excluded = calib.solve_optimisation()
        answer["solve_optimisation_s"] = time.perf_counter() - t0
        answer["solve_optimisation_cpu_s"] = time.process_time() - c0     # not counting waits for a shared core
    else:
        result = calib.solve(plotting=False, enable_logging=False, html_report=False)
        excluded = list(calib.outlier_indices)
        names = calib.calib_config["param_name"]
        out = {"parameters": dict(zip(names, map(float, result.x))),
               "std_dev": [float(s) for s in getattr(calib, "std_dev", [])]}
        (work / "figaroh_parameters.json").write_text(json.dumps(out, indent=1))
    answer.update(success=bool(result.success), objective_calls=calib.calls, parameters=len(result.x),
                  excluded=[int(i) for i in excluded])
    if request["mode"] == "fit":      # the scores are not part of the timed script, as for robocal calibrate
        answer.update(train_rmse_mm=rmse_mm(calib, training, result.x),
                      validation_rmse_mm=rmse_mm(calib, validation, result.x))
    Path(request["result"]).write_text(json.dumps(answer))


if __name__ == "__main__":
    main(sys.argv[1])
