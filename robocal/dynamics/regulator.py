"""The limited integral regulator on the tangential-force error (spec §4-D, block 430).

Without limits it is the patent's integral regulator sd_des = K eps, s_des = integral of sd_des.
With limits (reconstruction of §4-D), per tick of period T_s:
    v_cmd = K eps;  u = (v_cmd - z)/T_s;  w = sat(u, sdd_max);  z += T_s w
    sd = sat(z, sd_max);  z = sd   (anti-windup: the state never exceeds the speed limit)
    s = clip(s + T_s sd, 0, 1)     (the state follows the clip too)
Optional end braking (spec §13.12) caps |sd| by the discrete stopping speed for the distance d to
the end it moves towards (about sqrt(2 sdd_max d)), so the path stops at s = 0 or 1 within the
acceleration limit.

Stability in contact (docs/dynamics.md, "Stability of the force loop"). With ideal servos and an
exact force the loop against a contact of stiffness k_e is stable for g = T_s K L k_e < 2. On a
servoed arm with the force estimated from currents the limit is far lower and hardly depends on
k_e: the estimate subtracts the model's inertia at an acceleration differenced over two ticks,
while the current reflects the instantaneous one, so each change of commanded speed feeds back
about m_eff (a - a_hat) into the error, a path whose gain grows with the admittance. For the
UR5 of examples/force_deburring.py (m_eff = 8.7 kg along the path, 60 rad/s servos, 4 ms) the
gain margin reaches 1 at an admittance of 1.06e-3 m/(N s) (g = 0.085 at 2e4 N/m); the former
2e-3 had a gain margin of 0.53 and settled into the limit cycle bounded by the acceleration limit.
The design used there, a 10 Hz Butterworth filter on the estimate (MotionParams.force_filter_hz)
and admittance 7.58e-4 m/(N s) from force_loop.admittance_for_margins, keeps a gain margin >= 2.0
and a phase margin >= 54.6 deg for contact stiffnesses 1e3 to 1e5 N/m. The margins belong to the
arm, pose, servo gains and filter: compute them with force_loop.margins for another set-up.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError


@dataclass
class RegulatorState:
    """s (path parameter), sd 1/s, sdd 1/s^2 (the last applied acceleration)."""

    s: float = 0.0
    sd: float = 0.0
    sdd: float = 0.0


class TangentialForceRegulator:
    """gain K in 1/(N s); period T_s s; braking: stop smoothly at the ends of the path."""

    def __init__(self, gain: float, period: float = 0.004, braking: bool = False, s0: float = 0.0):
        if not (np.isfinite(gain) and gain > 0):
            raise InputError(f"regulator gain must be > 0, got {gain}", field="gain")
        if not period > 0:
            raise InputError(f"regulator period must be > 0, got {period}", field="period")
        if not 0.0 <= s0 <= 1.0:
            raise InputError(f"initial path parameter must be in [0, 1], got {s0}", field="s0")
        self.gain, self.period, self.braking = float(gain), float(period), braking
        self.state = RegulatorState(s=float(s0))

    def step(self, eps: float, sd_max: float, sdd_max: float, gain: float | None = None) -> RegulatorState:
        """Advance one tick with force error eps N and the projected limits at the current s."""
        st, ts = self.state, self.period
        k = self.gain if gain is None else gain
        hi = lo = sd_max
        if self.braking:     # stopping distance towards the end each direction would reach
            hi = min(sd_max, self._stopping_speed(1.0 - st.s, sdd_max))
            lo = min(sd_max, self._stopping_speed(st.s, sdd_max))
        z_prev = st.sd
        u = (k * eps - z_prev) / ts
        w = min(max(u, -sdd_max), sdd_max)
        z = min(max(z_prev + ts * w, -lo), hi)
        s_new = st.s + ts * z
        if not 0.0 <= s_new <= 1.0:      # the clip at the ends is part of the state (anti-windup)
            s_new = min(max(s_new, 0.0), 1.0)
            z = (s_new - st.s) / ts
        self.state = RegulatorState(s=s_new, sd=z, sdd=(z - z_prev) / ts)
        return self.state

    def _stopping_speed(self, distance: float, sdd_max: float) -> float:
        """Largest speed z that still stops within `distance`, slowing by a T_s per tick.

        With z = (n + f) a T_s (n integer, 0 <= f < 1) the ticks cover a T_s^2 ((n + 1) f + n (n + 1)/2);
        inverting that piecewise-linear map gives z, and the next tick's cap is exactly z - a T_s."""
        step = sdd_max * self.period
        if distance <= 0.0 or step <= 0.0:
            return 0.0
        units = distance / (step * self.period)
        n = float(np.floor(-0.5 + np.sqrt(0.25 + 2.0 * units)))
        f = min(max((units - n * (n + 1) / 2) / (n + 1), 0.0), 1.0)
        return step * (n + f)
