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
evaluation_<name>.json and evaluation_<name>.svg (robocal.viz.svg_torques).
A model identified from motor-side logs (its side file has a transmission) predicts motor-side logs: LOG.yaml
gives position and effort (motor encoders and currents; `sample_period_s` when there is no time column), the
motors' torques are scored per motor, and their errors mapped to the joints (tau = T^-T tau_m) per joint. A log
faster than the identification's max_rate_hz is reduced first (rate_reduction.py): its rows scored are the
kept rows (every r-th), against their raw readings. See docs/dynamics_motors.md.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robocal.dynamics.filtering import SignalOptions, process_log
from robocal.dynamics.identified_model import SIDE_FILE, IdentifiedDynamics, predict_torques
from robocal.dynamics.log_loading import load_joint_log, reduce_joint_log
from robocal.dynamics.motor_log import load_motor_log
from robocal.dynamics.reduced_model import model_columns, reduced_model
from robocal.errors import InputError
from robocal.io.output_folder import write_folder
from robocal.io.yaml_files import read_yaml
from robocal.workflows.config_keys import Cfg
from robocal.viz.svg_torques import joint_torques
from robocal.workflows.identify_urdf import joint_unit

LOG_KEYS = ("name", "position", "velocity", "effort", "time_column", "sample_period_s", "columns", "window")


@dataclass
class DynamicsEvaluation:
    """name of the log; recorded: the channels (recorded joints, or logged motors) and their units; t (n,) the
    scored raw rows' times; logged, filtered, predicted (n, nr) torques; rmse_logged, rmse_filtered (nr,);
    rows_total: the log's rows in the window; choices: the signal processing in words; for motor-side logs,
    joints and joint_rmse_logged, joint_rmse_filtered: the errors mapped to the joints (empty otherwise)."""

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
    joints: list[str] = field(default_factory=list)
    joint_units: list[str] = field(default_factory=list)
    joint_rmse_logged: np.ndarray = field(default_factory=lambda: np.zeros(0))
    joint_rmse_filtered: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def to_dict(self) -> dict:
        out = {"log": self.name, "recorded_joints": self.recorded, "torque_units": self.units,
               "rows_scored": int(len(self.t)), "rows_in_window": self.rows_total,
               "rmse_against_logged": dict(zip(self.recorded, self.rmse_logged.tolist())),
               "rmse_against_filtered": dict(zip(self.recorded, self.rmse_filtered.tolist())),
               "signal_processing": self.choices}
        if self.joints:
            out = {"logged_motors": out.pop("recorded_joints"), **out,
                   "joint_rmse_against_logged": dict(zip(self.joints, self.joint_rmse_logged.tolist())),
                   "joint_rmse_against_filtered": dict(zip(self.joints, self.joint_rmse_filtered.tolist())),
                   "joint_torque_units": self.joint_units}
        return out


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
    sig = dyn.signal
    t, q, v, tau, logged_tau, choices = _read_log(c, log_yaml, dyn, model, float(sig.get("max_rate_hz", 250.0)))
    window = c.get("window", [float(t[0]), float(t[-1]) + 1.0], types=list)
    if len(window) != 2 or not window[0] < window[1]:
        raise c.error("expected [start, stop] in seconds with start < stop", "window")
    opts = SignalOptions(cutoff_hz=float(sig["cutoff_hz"]), order=int(sig["order"]), decimate=1,
                         velocity_source=str(sig["velocity_source"]), edge_periods=float(sig["edge_periods"]))
    proc = process_log(t, q, v, tau, opts)
    proc.choices[:0] = choices
    pred_grid = predict_torques(model, dyn, proc.q, proc.v, proc.a)
    delays = np.array([dyn.delay_s.get(j, 0.0) for j in dyn.recorded])
    in_window = (t >= window[0]) & (t < window[1])
    # a reading at t is the model's torque at t - delay: both inside the filtered grid's trimmed span
    ok = in_window & (t - delays.max() >= proc.t[0]) & (t - delays.min() <= proc.t[-1])
    if ok.sum() < 2:
        raise c.error(f"no row of the log lies inside the window and the filter's trimmed edges "
                      f"({proc.t[0]:.4g} to {proc.t[-1]:.4g} s)", "window")
    ts = t[ok]
    predicted = np.column_stack([np.interp(ts - d, proc.t, pred_grid[:, k]) for k, d in enumerate(delays)])
    filtered = np.column_stack([np.interp(ts, proc.t, proc.effort[:, k]) for k in range(len(dyn.recorded))])
    logged = logged_tau[ok]
    units = [joint_unit(model, j) for j in dyn.recorded]
    out = DynamicsEvaluation(str(c.get("name", log_yaml.stem, types=str)), dyn.recorded, units, ts, logged, filtered,
                             predicted, np.sqrt(np.mean((predicted - logged) ** 2, axis=0)),
                             np.sqrt(np.mean((predicted - filtered) ** 2, axis=0)), int(in_window.sum()),
                             proc.choices)
    if dyn.transmission is not None:            # the motors' errors mapped to the joints they determine
        joints, _, to_joints = dyn.channels(model).joint_map(model)
        out.joints, out.joint_units = joints, [joint_unit(model, j) for j in joints]
        out.joint_rmse_logged = np.sqrt(np.mean(((predicted - logged) @ to_joints) ** 2, axis=0))
        out.joint_rmse_filtered = np.sqrt(np.mean(((predicted - filtered) @ to_joints) ** 2, axis=0))
    return out


def _read_log(c: Cfg, log_yaml: Path, dyn: IdentifiedDynamics, model, max_rate_hz: float):
    """(t, q, v or None (model order), channel torques, the raw readings' torques at t, choices) of LOG.yaml: a
    joint log (position, velocity, effort files) or, for a model of motor-side logs, a motor log."""
    period = None if c.get("sample_period_s") is None else c.number("sample_period_s", 0.0, positive=True)
    patterns = {str(k): str(v) for k, v in c.get("columns", {}, types=dict).items()}
    tr = dyn.transmission
    kinds = ("position", "effort") if tr is not None else ("position", "velocity", "effort")
    files = {k: str(log_yaml.parent / str(c.get(k, required=True, types=str))) for k in kinds}
    time_column = str(c.get("time_column", "t", types=str))
    if tr is not None:
        mlog = load_motor_log(files, tr.motors, dyn.recorded, time_column, period, patterns, max_rate_hz)
        q = model_columns(model, tr.joints, tr.joint_positions(mlog.position))
        return (mlog.t, q, None, dyn.effort.torques(mlog.effort), dyn.effort.torques(mlog.effort_raw),
                mlog.choices)
    log = load_joint_log(files, dyn.joints, time_column, patterns, period)
    rec = [dyn.joints.index(j) for j in dyn.recorded]
    log, raw, choices = reduce_joint_log(log, max_rate_hz)
    tau = dyn.effort.torques(log.effort[:, rec])
    return (log.t, model_columns(model, log.joints, log.q), model_columns(model, log.joints, log.v), tau,
            tau if raw is None else dyn.effort.torques(raw[:, rec]), choices)


def evaluation_figure(ev: DynamicsEvaluation) -> bytes:
    return joint_torques(ev.t, ev.logged, {"filtered torque": ev.filtered, "identified model": ev.predicted},
                         [j.replace("_joint", "") for j in ev.recorded], ev.units,
                         title=f"{ev.name}: logged torque (raw rows) vs the identified model's prediction").encode()


def write_evaluation(folder: str | Path, ev: DynamicsEvaluation) -> dict[str, Path]:
    """Add evaluation_<name>.json and evaluation_<name>.svg to the identify folder, atomically."""
    folder = Path(folder).resolve()
    files = {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}
    stem = f"evaluation_{ev.name}"
    files[f"{stem}.json"] = (json.dumps(ev.to_dict(), indent=1) + "\n").encode()
    files[f"{stem}.svg"] = evaluation_figure(ev)
    written = write_folder(folder, files, force=True)
    return {k: v for k, v in written.items() if k.startswith(stem)}
