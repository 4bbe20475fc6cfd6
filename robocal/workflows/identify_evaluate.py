"""`robocal evaluate IDENTIFY_DIR LOG.yaml`: predict the torques of a new log with an identified model and
score them at the log's own rows.

The model is what `robocal identify` wrote: the identified URDF and its side file dynamics.yaml
(identified_model.py), nothing of robocal's internal regressor. LOG.yaml describes one log like an entry
of the identify config's `logs:` (position, velocity, effort, time_column, columns; paths relative to
LOG.yaml) with an optional `window: [t0, t1]` (s) and `name`. The log's positions (and velocities) go
through the identification's own filter (the side file's cut-off, order, velocity source) on a uniform
grid; the model's torque is computed there (RNEA plus the joint terms) and interpolated to every raw row
of the log inside the filter's trimmed edges (a row's torque reading at t is the model's at t - delay).
Scored per recorded joint against the logged torque itself (effort mapped as at identification, no
filter) and against the same torque through the identification's low-pass. Outputs, added to the folder:
evaluation_<name>.json and evaluation_<name>.png.
"""
from __future__ import annotations

import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robocal.dynamics.filtering import SignalOptions, process_log
from robocal.dynamics.identified_model import SIDE_FILE, IdentifiedDynamics, predict_torques
from robocal.dynamics.log_loading import load_joint_log
from robocal.dynamics.reduced_model import model_columns, reduced_model
from robocal.errors import InputError
from robocal.io.output_folder import write_folder
from robocal.io.yaml_files import read_yaml
from robocal.workflows.config_keys import Cfg

LOG_KEYS = ("name", "position", "velocity", "effort", "time_column", "columns", "window")


@dataclass
class DynamicsEvaluation:
    """name of the log; recorded joints and their units; t (n,) the scored raw rows' times; logged,
    filtered, predicted (n, nr) torques; rmse_logged, rmse_filtered (nr,); rows_total: the log's rows in
    the window; choices: the signal processing in words."""

    name: str
    recorded: list[str]
    units: list[str]
    t: np.ndarray
    logged: np.ndarray
    filtered: np.ndarray
    predicted: np.ndarray
    rmse_logged: np.ndarray
    rmse_filtered: np.ndarray
    rows_total: int
    choices: list[str]

    def to_dict(self) -> dict:
        return {"log": self.name, "recorded_joints": self.recorded, "torque_units": self.units,
                "rows_scored": int(len(self.t)), "rows_in_window": self.rows_total,
                "rmse_against_logged": dict(zip(self.recorded, self.rmse_logged.tolist())),
                "rmse_against_filtered": dict(zip(self.recorded, self.rmse_filtered.tolist())),
                "signal_processing": self.choices}


def read_side_file(folder: Path) -> IdentifiedDynamics:
    path = folder / SIDE_FILE
    if not path.is_file():
        raise InputError(f"no {SIDE_FILE} in the folder: not a `robocal identify` output with an identified URDF",
                         source=str(folder), field=SIDE_FILE)
    return IdentifiedDynamics.from_dict(read_yaml(path), str(path))


def evaluate_dynamics(folder: str | Path, log_yaml: str | Path) -> DynamicsEvaluation:
    folder, log_yaml = Path(folder).resolve(), Path(log_yaml).resolve()
    dyn = read_side_file(folder)
    model = dyn.with_armature(reduced_model(folder / dyn.urdf, dyn.joints))
    c = Cfg(read_yaml(log_yaml), "", str(log_yaml))
    c.check_keys(LOG_KEYS)
    files = {k: str(log_yaml.parent / str(c.get(k, required=True, types=str))) for k in ("position", "velocity",
                                                                                         "effort")}
    log = load_joint_log(files, dyn.joints, str(c.get("time_column", "t", types=str)),
                         {str(k): str(v) for k, v in c.get("columns", {}, types=dict).items()})
    window = c.get("window", [float(log.t[0]), float(log.t[-1]) + 1.0], types=list)
    if len(window) != 2 or not window[0] < window[1]:
        raise c.error("expected [start, stop] in seconds with start < stop", "window")
    rec = [dyn.joints.index(j) for j in dyn.recorded]
    tau = dyn.effort.torques(log.effort[:, rec])
    sig = dyn.signal
    opts = SignalOptions(cutoff_hz=float(sig["cutoff_hz"]), order=int(sig["order"]), decimate=1,
                         velocity_source=str(sig["velocity_source"]), edge_periods=float(sig["edge_periods"]))
    proc = process_log(log.t, model_columns(model, log.joints, log.q), model_columns(model, log.joints, log.v), tau,
                       opts)
    pred_grid = predict_torques(model, dyn, proc.q, proc.v, proc.a)
    delays = np.array([dyn.delay_s.get(j, 0.0) for j in dyn.recorded])
    in_window = (log.t >= window[0]) & (log.t < window[1])
    # a reading at t is the model's torque at t - delay: both inside the filtered grid's trimmed span
    ok = in_window & (log.t - delays.max() >= proc.t[0]) & (log.t - delays.min() <= proc.t[-1])
    if ok.sum() < 2:
        raise c.error(f"no row of the log lies inside the window and the filter's trimmed edges "
                      f"({proc.t[0]:.4g} to {proc.t[-1]:.4g} s)", "window")
    t = log.t[ok]
    predicted = np.column_stack([np.interp(t - d, proc.t, pred_grid[:, k]) for k, d in enumerate(delays)])
    filtered = np.column_stack([np.interp(t, proc.t, proc.effort[:, k]) for k in range(len(rec))])
    logged = tau[ok]
    units = ["N" if model.joints[model.getJointId(j)].shortname().startswith("JointModelP") else "N m"
             for j in dyn.recorded]
    return DynamicsEvaluation(str(c.get("name", log_yaml.stem, types=str)), dyn.recorded, units, t, logged, filtered,
                              predicted, np.sqrt(np.mean((predicted - logged) ** 2, axis=0)),
                              np.sqrt(np.mean((predicted - filtered) ** 2, axis=0)), int(in_window.sum()),
                              proc.choices)


def evaluation_figure(ev: DynamicsEvaluation) -> bytes:
    from robocal.viz.plots import joint_torques   # optional dependency (matplotlib): only for a figure
    buf = io.BytesIO()
    joint_torques(ev.t, ev.logged, {"filtered torque": ev.filtered, "identified model": ev.predicted}, buf,
                  [j.replace("_joint", "") for j in ev.recorded], ev.units,
                  title=f"{ev.name}: logged torque (raw rows) vs the identified model's prediction")
    return buf.getvalue()


def write_evaluation(folder: str | Path, ev: DynamicsEvaluation) -> dict[str, Path]:
    """Add evaluation_<name>.json (and .png with matplotlib) to the identify folder, atomically."""
    folder = Path(folder).resolve()
    files = {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}
    stem = f"evaluation_{ev.name}"
    files[f"{stem}.json"] = (json.dumps(ev.to_dict(), indent=1) + "\n").encode()
    try:
        files[f"{stem}.png"] = evaluation_figure(ev)
    except ImportError:
        pass
    written = write_folder(folder, files, force=True)
    return {k: v for k, v in written.items() if k.startswith(stem)}
