"""Tangential contact force that survives joint stiction: tare at the approach speed, torque-constant
scale from the approach, the contact line measured at that speed, then regulation on the line.

A current-based estimate (external_force.py) subtracts a friction model; what is left wrong depends on
the joint speeds (friction level, Stribeck rise, viscous term, any lag between the current sample and
the differenced motion) and on the set-point acceleration (the servo's torque steps at the ticks, which
a difference over two ticks cannot see). A joint at rest holds anything up to its breakaway torque.
So the observer uses the estimate only where these errors cancel, and positions (exact) elsewhere:

* free space (`phase == "free"`): per joint, the mean external torque over the last `tare_ticks`
  samples (skipping the newest `guard_ticks`) is the tare, taken only for joints that slid in one
  direction through the whole window, with their mean speed (the cruise speed). Whatever depends on
  the speed alone is the same a few millimetres later at the same speed, so the tare removes it.
  The approach samples also give the torque-constant scale (torque_scale.py, gravity change).
* press (`"press"`): once the tared force exceeds `detect` x f_des, the regulator is given no force,
  so the path keeps the free-space feed: the joints keep the cruise speed (slowed only by the servo's
  compliance against the contact) and the set-point does not accelerate, which is where the tare
  holds. Each sample whose rows are trusted is added to the contact line F = k (x - x_c)
  (contact_line.py). The press ends when the line's force at f_des is known to `precision` x f_des
  (1 sigma, from the free-space noise), when a trusted sample reaches f_des, or when the rows stop
  being trusted with at least two samples in.
* line (`"line"`): the regulator is given the line at the commanded position: the force the set-point
  produces once the servos reach it. It is noise-free, needs no filter and no trust rule, and the loop
  it closes (r_k+1 = r_k + T a (f_des - k r_k)) is a first-order lag for T a k < 1.

Rows and force: the contact is taken as a force along the path tangent u at the tool point (no
moment, no side force): then F_u = a . tau / |a|^2 over the trusted rows, a = J_rows^T u. A joint's
row is trusted when the joint is tared and slides in its cruise direction at >= `speed_ratio` of the
cruise speed; the sample is trusted when those rows see u (noise at most `noise_gain` x that of all
rows). A free 3-component force is not determined by the rows left: joints 2-4 of a UR5 have parallel
axes, and their rows cannot see a force along that axis.

Raw values (free space, and in contact before the line exists) are low-passed (`filter_hz`, the force
loop's filter); the press's 0 and the line are not.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError
from robocal.dynamics.contact_line import ContactLine
from robocal.dynamics.force_filter import ForceFilter
from robocal.dynamics.torque_scale import ScaleEstimate, torque_scale


@dataclass
class ObserverSettings:
    """tare_ticks, guard_ticks: the tare window and the newest samples it skips; slide_velocity rad/s:
    a joint slower than this is not sliding; speed_ratio: a row is trusted in contact at >= this
    fraction of the joint's cruise speed; noise_gain: how much noisier than the estimate from all rows
    a trusted estimate may be; detect: contact threshold (fraction of f_des); precision: the press
    ends when the line's force at f_des has this standard deviation (fraction of f_des); scale_band:
    approach samples within this fraction of the cruise speed enter the scale; kt_tolerance: the
    torque constants' relative tolerance (prior of the scale, as 2 sigma); approach_ticks: the longest
    approach kept for the scale; filter_hz: low-pass of raw values (None: none)."""

    tare_ticks: int = 50
    guard_ticks: int = 10
    slide_velocity: float = 1e-3
    speed_ratio: float = 0.5
    noise_gain: float = 2.0
    detect: float = 0.1
    precision: float = 0.01
    scale_band: float = 0.1
    kt_tolerance: float = 0.05
    approach_ticks: int = 2000
    filter_hz: float | None = 10.0

    def __post_init__(self):
        if self.tare_ticks < 2 or self.guard_ticks < 0 or self.approach_ticks < self.tare_ticks:
            raise InputError("observer windows: tare_ticks >= 2, guard_ticks >= 0, approach_ticks >= tare_ticks",
                             field="tare_ticks")
        if not (self.slide_velocity > 0 and 0 < self.speed_ratio < 1 and self.noise_gain >= 1
                and 0 < self.detect < 1 and self.precision > 0 and self.kt_tolerance > 0):
            raise InputError("observer slide_velocity, precision, kt_tolerance > 0; speed_ratio, detect in "
                             "(0, 1); noise_gain >= 1", field="slide_velocity")


class ContactForceObserver:
    """Per-tick tangential force for the regulator from the external joint torques of the current-based
    estimate. f_des N the set-point; period s the control tick (for the filter)."""

    def __init__(self, f_des: float, settings: ObserverSettings | None = None, period: float = 0.004):
        if not np.isfinite(f_des) or f_des <= 0:
            raise InputError(f"observer needs a force setpoint > 0, got {f_des}", field="f_des")
        self.f_des, self.cfg = float(f_des), settings or ObserverSettings()
        self.filter = ForceFilter(self.cfg.filter_hz, period) if self.cfg.filter_hz else None
        self.window: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=self.cfg.tare_ticks + self.cfg.guard_ticks)
        self.approach: deque[tuple[np.ndarray, np.ndarray, np.ndarray]] = deque(maxlen=self.cfg.approach_ticks)
        self.phase = "free"
        self.tare = self.cruise = None     # (n,): nan for joints not tared
        self.scale: ScaleEstimate | None = None
        self.line = ContactLine()
        self.frozen: tuple[float, float, float] | None = None     # k, b, x_ref of the line in use
        self.noise = np.nan                # std of a trusted free-space sample, N
        self.output, self.trusted = 0.0, False

    # ---- pieces --------------------------------------------------------------------------------
    def _update_tare(self) -> None:
        old = list(self.window)[: len(self.window) - self.cfg.guard_ticks]
        if len(old) < 2:
            return
        tau = np.array([t for t, _ in old])
        v = np.array([w for _, w in old])
        steady = np.all(np.abs(v) >= self.cfg.slide_velocity, axis=0) & np.all(np.sign(v) == np.sign(v[-1]), axis=0)
        self.tare = np.where(steady, tau.mean(axis=0), np.nan)
        self.cruise = np.where(steady, v.mean(axis=0), np.nan)

    @property
    def tare_ready(self) -> bool:
        """True once the tare window is full (contact is only detected from then on)."""
        return len(self.window) == self.window.maxlen and self.tare is not None

    def trusted_rows(self, v: np.ndarray) -> np.ndarray:
        """(n,) bool: tared joints sliding in their cruise direction at >= speed_ratio of the cruise speed."""
        if self.cruise is None:
            return np.zeros(np.size(v), bool)
        ok = np.isfinite(self.cruise)
        ratio = np.where(ok, np.asarray(v, float) / np.where(ok, self.cruise, 1.0), 0.0)
        return ok & (ratio >= self.cfg.speed_ratio)

    def force_from_rows(self, torque: np.ndarray, jacobian: np.ndarray, u: np.ndarray,
                        rows: np.ndarray) -> float | None:
        """Force along u from the given joints' rows of torque = J_lin^T (F u), or None when those rows
        see u with more than `noise_gain` times the noise of all rows."""
        a_all = np.asarray(jacobian, float).T @ u
        a = a_all[rows]
        if not rows.any() or np.linalg.norm(a) * self.cfg.noise_gain < np.linalg.norm(a_all):
            return None
        return float(a @ np.asarray(torque, float)[rows] / (a @ a))

    def _raw(self, value: float) -> float:
        return float(self.filter.push(value)) if self.filter is not None else float(value)

    def _scaled(self, force: float) -> float:
        return force / (self.scale.scale if self.scale is not None else 1.0)

    def _start_press(self, jacobian: np.ndarray, u: np.ndarray) -> None:
        """At contact: freeze the tare, estimate the scale and the noise of a trusted sample."""
        self.phase = "press"
        keep = list(self.approach)[: max(len(self.approach) - self.cfg.guard_ticks, 0)]
        if keep:
            tau, g, v = (np.array([s[i] for s in keep]) for i in range(3))
            self.scale = torque_scale(tau, g, v, np.nan_to_num(self.cruise), self.cfg.scale_band,
                                      self.cfg.kt_tolerance)
        else:               # no gravity given: the nominal torque constants
            self.scale = ScaleEstimate(1.0, 0.0, np.inf, self.cfg.kt_tolerance / 2, (), ())
        rows = np.isfinite(self.tare)
        old = [t for t, _ in list(self.window)[: len(self.window) - self.cfg.guard_ticks]]
        forces = [self.force_from_rows(t - np.nan_to_num(self.tare), jacobian, u, rows) for t in old]
        forces = [f for f in forces if f is not None]
        self.noise = float(np.std(forces, ddof=1)) / self.scale.scale if len(forces) > 2 else np.nan

    def _freeze(self) -> None:
        k, b = self.line.coefficients()
        self.frozen, self.phase = (k, b, self.line.x_ref), "line"

    def line_std(self) -> float:
        """Standard deviation of the line's force at f_des, N (the free-space noise or the residual
        scatter, the larger)."""
        if self.line.coefficients() is None:
            return float("inf")
        sigma = np.nanmax([self.noise, self.line.residual_std(), 0.0])
        return self.line.prediction_std(self.line.position_of(self.f_des), sigma)

    # ---- one tick ------------------------------------------------------------------------------
    def update(self, torque: np.ndarray, jacobian: np.ndarray, u: np.ndarray, x_u: float,
               v: np.ndarray, x_cmd: float | None = None, gravity: np.ndarray | None = None) -> float:
        """One tick: external joint torques (n,) N m of the current-based estimate, the translational
        Jacobian (3, n) of the tool point, the unit tangent u (3,), the tool position along u m from the
        measured joints, the joint velocities (n,) rad/s, x_cmd m the commanded tool position along u
        (x_u when None) and gravity (n,) N m the model's g(q) (no scale estimate without it)
        -> the tangential force N for the regulator."""
        torque, v = np.asarray(torque, float), np.asarray(v, float)
        x_cmd = x_u if x_cmd is None else x_cmd
        if self.phase == "line":
            k, b, x_ref = self.frozen
            self.output, self.trusted = k * (x_cmd - x_ref) + b, False
            return self.output
        if self.phase == "free":
            self.window.append((torque.copy(), v.copy()))
            if gravity is not None:
                self.approach.append((torque.copy(), np.asarray(gravity, float).copy(), v.copy()))
            if len(self.window) > self.cfg.guard_ticks:
                self._update_tare()
        tared = torque - (np.nan_to_num(self.tare) if self.tare is not None else 0.0)
        force = self.force_from_rows(tared, jacobian, u, self.trusted_rows(v))
        self.trusted = force is not None
        if self.phase == "free":
            if self.trusted and self.tare_ready and force > self.cfg.detect * self.f_des:
                self._start_press(jacobian, u)
            else:
                every = self.force_from_rows(tared, jacobian, u, np.ones(v.size, bool))
                self.output = self._raw(force if self.trusted else every)
                return self.output
        # press: the regulator keeps the feed while the line is measured at the cruise speed
        if self.trusted:
            force = self._scaled(force)
            self.line.add(x_u, force)
        line_ok = self.line.coefficients() is not None
        if line_ok and (not self.trusted or force >= self.f_des or self.line_std() <= self.cfg.precision * self.f_des):
            self._freeze()
            return self.update(torque, jacobian, u, x_u, v, x_cmd, gravity)
        if self.trusted and force < self.f_des:
            self.output = 0.0
        else:                # no line yet: the tared estimate from every row (error up to the stuck joints')
            self.output = self._raw(self._scaled(self.force_from_rows(tared, jacobian, u, np.ones(v.size, bool))))
        return self.output
