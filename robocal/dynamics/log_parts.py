"""The logs an identification uses, each with its training and validation windows, filtered and turned
into regressor rows.

A `LogPart` is one log (positions, velocities, efforts of the model's joints at its own time stamps) with
the torques of the recorded joints and the windows of it that train and validate; several parts (logs, or
the same log listed twice with other windows) give one fit. Every part goes through the same filter: the
cut-off is the largest the spectral rule (filtering.py) gives over the parts' training windows. Each part
keeps its own grid and decimation. Training samples of a part closer to one of its validation windows than
the filter's reach are left out (the zero-phase filter would carry validation data into them).
A motor-side log (docs/dynamics_motors.md) is a part too: its joint positions come from the motor encoders
through the transmission (no velocities), its `tau` holds the logged motors' torques, and the rows are the
motors' equations (channels.py); a log reduced from kHz rates carries the raw readings at its rows in `tau_raw`.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pinocchio as pin

from robocal.dynamics.channels import Channels, channel_regressor
from robocal.dynamics.filtering import ProcessedLog, SignalOptions, parallel_filter, process_log
from robocal.dynamics.log_loading import JointLog
from robocal.dynamics.reduced_model import model_columns
from robocal.dynamics.regression import Regressor

Window = tuple[float, float]


@dataclass
class LogPart:
    """log: the joint log; tau (T, nr): the channels' torques (recorded joints' or logged motors'; N m, N) at
    log.t; train, validate: lists of windows (s, log time); name: how messages call it; tau_raw: the raw
    readings at log.t when `tau` went through a rate reduction's anti-alias filter (None: tau is raw);
    choices: what was done to the log before (the rate reduction), said first in the signal processing."""

    log: JointLog
    tau: np.ndarray
    train: list[Window]
    validate: list[Window] = field(default_factory=list)
    name: str = "log"
    tau_raw: np.ndarray | None = None
    choices: list[str] = field(default_factory=list)


@dataclass
class PreparedPart:
    """A part after filtering: processed (full rate), regressor (decimated rows, every candidate column),
    t (decimated times), train and check masks over them, delays-free torques through `torque`."""

    part: LogPart
    processed: ProcessedLog
    regressor: Regressor
    t: np.ndarray
    train: np.ndarray
    check: np.ndarray
    coulomb_width: np.ndarray
    motor_width: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def torque(self, mask: np.ndarray, delays: np.ndarray) -> np.ndarray:
        """Filtered torques (n, nr) at the decimated samples of `mask`, joint k's read delays[k] s later
        (its reading lags the motion by that much)."""
        p = self.processed
        t = self.t[mask]
        return np.column_stack([np.interp(t + d, p.t, p.effort[:, k]) for k, d in enumerate(delays)])

    def torque_column(self, mask: np.ndarray, k: int, delay: float) -> np.ndarray:
        """Column k of `torque` alone."""
        return np.interp(self.t[mask] + delay, self.processed.t, self.processed.effort[:, k])

    def logged(self, mask: np.ndarray, delays: np.ndarray) -> np.ndarray:
        """The logged torques themselves (no filter), linearly interpolated to the same times."""
        log, t = self.part.log, self.t[mask]
        tau = self.part.tau if self.part.tau_raw is None else self.part.tau_raw
        return np.column_stack([np.interp(t + d, log.t, tau[:, k]) for k, d in enumerate(delays)])


def within(t: np.ndarray, windows: list[Window]) -> np.ndarray:
    out = np.zeros(len(t), bool)
    for a, b in windows:
        out |= (t >= a) & (t < b)
    return out


def common_cutoff(parts: list[LogPart], model: pin.Model, signal: SignalOptions) -> tuple[float | None, str]:
    """The cut-off every part is filtered with: the configured one, or with one part None (its own rule,
    said in its choices), with several the largest the rule gives over the parts' training windows."""
    if signal.cutoff_hz is not None or len(parts) == 1:
        return signal.cutoff_hz, ""
    cut = [process_log(p.log.t, model_columns(model, p.log.joints, p.log.q), model_columns(model, p.log.joints,
                                                                                           p.log.v),
                       p.tau, signal, spectrum_window=p.train).cutoff_hz for p in parts]
    return max(cut), ("cut-off {:.3g} Hz: the largest of the spectral rule over the parts' training windows ("
                      .format(max(cut)) + ", ".join(f"{c:.3g}" for c in cut) + " Hz)")


def prepare_parts(model: pin.Model, parts: list[LogPart], channels: Channels, signal: SignalOptions,
                  joint_terms: dict[int, tuple[str, ...]], coulomb_width: float) -> list[PreparedPart]:
    """Filter every part, build its regressor with every column of `joint_terms` ({velocity index: terms}) and
    the channels' motor terms (parallel filtering, decimation) and its masks. The Coulomb tanh width:
    coulomb_width x each term joint's (and each motor channel's) RMS speed over all training samples."""
    fc, why = common_cutoff(parts, model, signal)
    opts = replace(signal, cutoff_hz=fc)
    procs = []
    for p in parts:
        proc = process_log(p.log.t, model_columns(model, p.log.joints, p.log.q),
                           model_columns(model, p.log.joints, p.log.v), p.tau, opts, spectrum_window=p.train)
        if why:
            proc.choices[1] = why
        proc.choices[:0] = p.choices
        procs.append(proc)
    term_joints = channels.term_joints()
    train = [(proc, within(proc.t, p.train)) for p, proc in zip(parts, procs)]
    speeds = np.concatenate([proc.v[m][:, term_joints] for proc, m in train])
    width = coulomb_width * np.sqrt(np.mean(speeds ** 2, axis=0))
    motor_width = np.zeros(0)
    if channels.motors:
        rates = np.concatenate([channels.motor_kinematics(proc.q[m], proc.v[m], proc.a[m])[1] for proc, m in train])
        motor_width = coulomb_width * np.sqrt(np.mean(rates ** 2, axis=0))
    out = []
    for p, proc in zip(parts, procs):
        reg = channel_regressor(model, proc.q, proc.v, proc.a, channels, joint_terms, width, motor_width,
                                replace=False).transformed(lambda X, proc=proc: parallel_filter(proc, X))
        t = proc.decimated(proc.t)
        guard = signal.edge_periods / proc.cutoff_hz
        near = [(a - guard, b + guard) for a, b in p.validate]
        out.append(PreparedPart(p, proc, reg, t, within(t, p.train) & ~within(t, near), within(t, p.validate),
                                width, motor_width))
    return out


def stack(regs: list[Regressor]) -> Regressor:
    first = regs[0]
    return Regressor(np.concatenate([r.X for r in regs]), first.names, first.n_inertial, first.recorded)
