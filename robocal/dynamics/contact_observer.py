"""Tangential contact force that survives joint stiction: tare, trust rule and a contact-stiffness observer.

A current-based estimate (external_force.py) is only as good as the friction the estimator subtracts.
On a real joint at rest the friction is anything up to its breakaway torque, so at rest in contact the
estimate can be off by sum_j |dq_j| F_s,j (dq = J^-1 [u; 0], 14.6 N for the UR5 of
examples/force_deburring.py); and a friction or torque-constant error biases it even while sliding.
This observer works on the tangential component F_u of that estimate, once per tick:

* tare: in free space the estimate should read 0. Its mean over the last `tare_ticks` trusted samples
  (skipping the newest `guard_ticks`, which may already hold contact) is subtracted. The Coulomb part
  of a friction-level error depends only on the signs of the joint velocities, and the gravity part
  of a torque-constant error only on the pose: both are the same when pressing on along the path a
  few millimetres later, so the tare removes them (a torque-constant scale error on the contact force
  itself stays: an estimate (1 + e) F regulates to F_des/(1 + e)).
* trust rule: a joint slides when |v_j| >= `slide_velocity` in the direction it had at the tare; only
  then is its friction torque the model's. A joint that does not could hide up to |dq_j| F_s,j of
  static friction along the tangent; a sample is trusted when those amounts, summed over the joints
  not sliding, stay within `budget` x f_des.
* contact observer: once contact is detected (tared estimate above `detect` x f_des), trusted samples
  (F_u, x_u) (x_u the TCP position along u from the measured joints) fit the contact line
  F_u = k (x_u - x_c) by least squares. An untrusted sample is replaced by the line at the measured
  x_u: joint positions are measured exactly, so the force the contact sees follows from them while
  the currents cannot tell friction from force. Until the line is determined (enough trusted samples
  over enough force), and in free space, an untrusted sample is used as it is (tared): its error is
  then bounded by the static friction the stuck joints can hide.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError


@dataclass
class ObserverSettings:
    """tare_ticks, guard_ticks: the tare window and the newest samples it skips; slide_velocity rad/s:
    the speed above which a joint is taken as sliding; noise_gain: how much noisier than the estimate
    from all joints a trusted estimate from the sliding joints may be; detect: contact threshold
    (fraction of f_des); fit_samples, fit_span: the least trusted contact samples and force range
    (fraction of f_des) that determine the contact line; deadband: while the force comes from the
    contact line, a value within deadband x f_des of f_des is reported as f_des (the regulator
    stops instead of hunting stick-slip steps smaller than that)."""

    tare_ticks: int = 50
    guard_ticks: int = 10
    slide_velocity: float = 1e-3
    noise_gain: float = 2.0
    deadband: float = 0.02
    detect: float = 0.1
    fit_samples: int = 5
    fit_span: float = 0.25

    def __post_init__(self):
        if self.tare_ticks < 1 or self.guard_ticks < 0 or self.fit_samples < 2:
            raise InputError("observer windows: tare_ticks >= 1, guard_ticks >= 0, fit_samples >= 2",
                             field="tare_ticks")
        if not (self.slide_velocity > 0 and self.noise_gain >= 1 and 0 < self.detect < 1 and self.fit_span > 0):
            raise InputError("observer slide_velocity, detect, fit_span must be > 0 (detect < 1), noise_gain >= 1",
                             field="slide_velocity")


class ContactForceObserver:
    """Per-tick tangential force for the regulator, from the external joint torques of the current-based
    estimate. f_des N the setpoint; the contact is taken as a force at the tool point (no moment)."""

    def __init__(self, f_des: float, settings: ObserverSettings | None = None):
        if not np.isfinite(f_des) or f_des <= 0:
            raise InputError(f"observer needs a force setpoint > 0, got {f_des}", field="f_des")
        self.f_des, self.cfg = float(f_des), settings or ObserverSettings()
        self.history: deque[np.ndarray] = deque(maxlen=self.cfg.tare_ticks + self.cfg.guard_ticks)
        self.tare, self.signs, self.in_contact = None, None, False
        self._sums = np.zeros(5)          # n, sum x, sum F, sum x^2, sum x F of trusted contact samples
        self._x_ref = 0.0                 # x_u at contact detection: the fit works on x_u - x_ref
        self._f_range = [np.inf, -np.inf]
        self.output, self.trusted = 0.0, False

    def sliding(self, v: np.ndarray) -> np.ndarray:
        """(n,) bool: the joints whose friction torque is the model's: moving and, in contact, in the
        direction they had in free space (the tare holds for that direction only)."""
        moving = np.abs(v) >= self.cfg.slide_velocity
        return moving if not self.in_contact else moving & (np.sign(v) == self.signs)

    def force_from_rows(self, torque: np.ndarray, jacobian: np.ndarray, u: np.ndarray,
                        rows: np.ndarray) -> float | None:
        """Tangential force from the given joints' rows of torque = J_lin^T f, or None when those rows
        do not determine it within `noise_gain` times the noise of the estimate from every joint."""
        if rows.sum() < 3:
            return None
        gain_all = np.linalg.norm(np.linalg.pinv(jacobian.T).T @ u)
        pinv = np.linalg.pinv(jacobian[:, rows].T)            # (3, k): f = pinv @ torque[rows]
        if np.linalg.norm(pinv.T @ u) > self.cfg.noise_gain * gain_all:
            return None
        return float(u @ (pinv @ torque[rows]))

    @property
    def tare_ready(self) -> bool:
        """True once the tare window is full (contact is only detected from then on)."""
        return len(self.history) == self.history.maxlen

    @property
    def contact_line(self) -> tuple[float, float] | None:
        """(k N/m, F at x_u = x_ref, the position where contact was detected), or None while undetermined."""
        n, sx, sf, sxx, sxf = self._sums
        if n < self.cfg.fit_samples or self._f_range[1] - self._f_range[0] < self.cfg.fit_span * self.f_des:
            return None
        det = n * sxx - sx * sx
        if det <= 0:
            return None
        k = (n * sxf - sx * sf) / det
        return (k, (sf - k * sx) / n) if k > 0 else None

    def update(self, torque: np.ndarray, jacobian: np.ndarray, u: np.ndarray, x_u: float,
               v: np.ndarray, x_cmd: float | None = None) -> float:
        """One tick: external joint torques (n,) N m of the current-based estimate, the translational
        Jacobian (3, n) of the tool point, the unit tangent u (3,), the tool position along u m and
        the joint velocities (n,) rad/s, and x_cmd m the commanded tool position along u (the
        setpoint) -> the tangential force N for the regulator. An untrusted sample in contact is the
        contact line at x_cmd: the force the setpoint will produce once the servos reach it, so the
        regulator does not wind up against joints that stick (at x_u when x_cmd is None)."""
        rows = self.sliding(v)
        if not self.in_contact and rows.any():      # free space: the per-joint tare, sliding joints only
            self.history.append(np.where(rows, torque, np.nan))
            self.signs = np.where(rows, np.sign(v), 0.0 if self.signs is None else self.signs)
            if len(self.history) > self.cfg.guard_ticks:
                old = np.array(list(self.history)[: len(self.history) - self.cfg.guard_ticks])
                seen = np.isfinite(old).sum(axis=0)
                self.tare = np.where(seen > 0, np.nansum(old, axis=0) / np.maximum(seen, 1), 0.0)
        tared = torque - (self.tare if self.tare is not None else 0.0)
        force = self.force_from_rows(tared, jacobian, u, rows)
        self.trusted = force is not None
        if not self.in_contact:
            if self.trusted and self.tare_ready and force > self.cfg.detect * self.f_des:
                self.in_contact, self._x_ref = True, float(x_u)
            else:   # untrusted in free space: every joint's row, tared (error bounded by the stuck joints)
                self.output = force if self.trusted else float(u @ np.linalg.pinv(jacobian.T) @ tared)
                return self.output
        x_u = x_u - self._x_ref
        x_line = x_u if x_cmd is None else x_cmd - self._x_ref
        if self.trusted:
            self._sums += (1.0, x_u, force, x_u * x_u, x_u * force)
            self._f_range = [min(self._f_range[0], force), max(self._f_range[1], force)]
            self.output = force
        else:
            line = self.contact_line
            if line is None:
                self.output = float(u @ np.linalg.pinv(jacobian.T) @ tared)
            else:
                self.output = line[0] * x_line + line[1]
                if abs(self.output - self.f_des) <= self.cfg.deadband * self.f_des:
                    self.output = self.f_des
        return self.output
