"""Discrete-time model of the tangential-force loop in contact, and its stability margins.

The loop closed by `PathGenerator` against a contact of stiffness k_e, linearised at rest
(docs/dynamics.md, "Stability of the force loop"); r is the setpoint along the path tangent u:

* regulator, once per period T:  r_k+1 = r_k + T a (f_des - y_k)      (a = admittance, m/(N s))
* servo + contact, between ticks: the joint setpoints r J^+ [u; 0] ramp from r_k-1 to r_k (the
  drive interpolates, with velocity feed-forward); per-joint PID on the joint inertia M, friction
  linearised at rest (a damper C), the contact a spring k_e (u^T J)^T (u^T J):
      M x'' = Kp (dq r - x) + Ki int(dq r - x) + Kd (dq r' - x') - k_e J_u^T J_u x - C x'
* estimator: current-based with central differences, so one tick late, and subtracting the
  model's inertia and friction at the differenced acceleration and velocity:
      F_hat_k = dq^T [servo torque at t_k-1 - M (x_k - 2 x_k-1 + x_k-2)/T^2 - C (x_k - x_k-2)/(2 T)]
  (the contact force when the motion is slow, wrong by about m_eff (a - a_hat) when it is not);
* an optional low-pass filter H(z) on F_hat (`ForceFilter`), y = H F_hat;
* an optional sensor delay of d ticks (positions and currents reach the controller late): z^-d.

The open loop is L(z) = T a/(z - 1) z^-d H(z) P(z), P the setpoint-to-estimate response of the
servo-contact-estimator chain, built exactly (matrix exponential over one period) from the per-tick
linear map. `margins` gives the gain and phase margins and whether the closed loop is stable
(eigenvalues of the closed-loop map); `admittance_for_margins` picks the largest admittance that
keeps given margins over a range of contact stiffness. Gravity stiffness and Coriolis terms are
left out (at rest they are small against the servo gains); the current loop is taken as ideal.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.linalg import expm

from robocal.errors import InputError
from robocal.dynamics.force_filter import ForceFilter
from robocal.dynamics.stick_slip import StickSlipFriction

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass(frozen=True)
class TangentLoop:
    """The servoed arm linearised at rest in contact, seen through the path tangent.

    mass (n, n) kg m^2 (joint-space inertia); kp N m/rad, ki N m/(rad s), kd N m s/rad (n,) the
    per-joint PID; friction (n,) N m s/rad, the friction slope at rest; direction (n,) rad/m, the
    joint motion per metre along the tangent with the orientation held (J^+ [u; 0]); jacobian_u
    (n,) m/rad, the tangent row u^T J (the contact spring acts through it); period s;
    current_bandwidth rad/s of a first-order current loop (None: ideal, the torque is the PID's);
    delay: sensor delay in ticks (the measurements reach the estimator that many ticks late)."""

    mass: np.ndarray
    kp: np.ndarray
    ki: np.ndarray
    kd: np.ndarray
    friction: np.ndarray
    direction: np.ndarray
    jacobian_u: np.ndarray
    period: float = 0.004
    current_bandwidth: float | None = None
    delay: int = 0

    def __post_init__(self):
        n = self.direction.size
        shapes = [np.shape(self.mass) == (n, n)] + [np.shape(v) == (n,) for v in
                                                    (self.kp, self.ki, self.kd, self.friction, self.jacobian_u)]
        lag_ok = (self.current_bandwidth is None or self.current_bandwidth > 0) and self.delay >= 0
        if not all(shapes) or not self.period > 0 or np.any(np.asarray(self.kp) <= 0) or not lag_ok:
            raise InputError("tangent loop: mass (n, n), gains, friction, direction and tangent row (n,), "
                             "kp > 0 and period > 0 required", field="mass")

    @property
    def effective_mass(self) -> float:
        """kg: the inertia felt along the tangent, dq^T M dq."""
        return float(self.direction @ self.mass @ self.direction)

    @property
    def servo_stiffness(self) -> float:
        """N/m: the proportional servo gain felt along the tangent, dq^T Kp dq."""
        return float(self.direction @ (self.kp * self.direction))


@dataclass(frozen=True)
class Margins:
    """gain_margin (factor; inf when the phase never reaches -180 deg), phase_margin deg (nan
    when |L| > 1 up to Nyquist),
    crossover_hz (|L| = 1), phase_crossover_hz (phase -180 deg: the frequency an instability
    oscillates at), stable (closed-loop eigenvalues inside the unit circle), spectral_radius."""

    gain_margin: float
    phase_margin: float
    crossover_hz: float
    phase_crossover_hz: float
    stable: bool
    spectral_radius: float


def tangent_loop(model: pin.Model, q: np.ndarray, frame_id: int, gains, tangent: np.ndarray,
                 friction=None, period: float = 0.004, current_bandwidth: float | None = None,
                 delay: int = 0) -> TangentLoop:
    """Linearise the servoed arm at configuration q (at rest) for a path tangent (3,) at the tool.

    gains (kp, ki, kd) per joint as the simulator's servos use them; friction a FrictionModel or
    None (a `StickSlipFriction` enters through its sliding slope: viscous only, the dry part is
    not linear at rest). The servos hold the tool on the path, so a setpoint step of r metres along u moves the
    joint setpoints by r J^+ [u; 0]."""
    u = np.asarray(tangent, float)
    u = u / np.linalg.norm(u)
    data = model.createData()
    J = pin.computeFrameJacobian(model, data, q, frame_id, _LWA)
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    slope = np.zeros(model.nv)
    if isinstance(friction, StickSlipFriction):
        slope = friction.viscous.copy()
    elif friction is not None:   # d tau_f/dv at v = 0: Coulomb and Stribeck through the tanh, plus viscous
        slope = (friction.coulomb + friction.stribeck) / friction.smoothing + friction.viscous
    kp, ki, kd = (np.asarray(g, float).copy() for g in gains)
    return TangentLoop(mass, kp, ki, kd, slope, np.linalg.pinv(J) @ np.r_[u, 0.0, 0.0, 0.0], J[:3].T @ u, period,
                       current_bandwidth, int(delay))


def plant_map(loop: TangentLoop, stiffness: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(A, B, C, D) of one tick: input the new setpoint r_k (m along u), output F_hat_k (N).

    State after tick k: joint deviations x_k, their rates, the servo integrals and, with a lagging
    current loop, the motor torques (t_k); r_k, r_k-1; x_k-1 (for the central differences). Between ticks the setpoint moves at the constant rate
    (r_k - r_k-1)/T; the exact transition over T is a matrix exponential."""
    n, T = loop.direction.size, loop.period
    dq, Minv = loop.direction, np.linalg.inv(loop.mass)
    contact = float(stiffness) * np.outer(loop.jacobian_u, loop.jacobian_u)
    lag = loop.current_bandwidth is not None
    nt = n if lag else 0                          # motor torques, when the current loop lags
    # continuous state [x, x', ie, tau (lag only), r, r']; the PID torque is linear in it
    size = 3 * n + nt + 2
    ir = 3 * n + nt
    pid = np.zeros((n, size))
    pid[:, :n] = -np.diag(loop.kp)
    pid[:, n:2 * n] = -np.diag(loop.kd)
    pid[:, 2 * n:3 * n] = np.diag(loop.ki)
    pid[:, ir] = loop.kp * dq
    pid[:, ir + 1] = loop.kd * dq
    torque = np.zeros((n, size))                  # the torque the motors apply
    if lag:
        torque[:, 3 * n:4 * n] = np.eye(n)
    else:
        torque = pid
    Ac = np.zeros((size, size))
    Ac[:n, n:2 * n] = np.eye(n)
    Ac[n:2 * n] = Minv @ torque
    Ac[n:2 * n, :n] -= Minv @ contact
    Ac[n:2 * n, n:2 * n] -= Minv @ np.diag(loop.friction)
    Ac[2 * n:3 * n, :n] = -np.eye(n)
    Ac[2 * n:3 * n, ir] = dq
    if lag:
        Ac[3 * n:4 * n] = loop.current_bandwidth * (pid - torque)
    Ac[ir, ir + 1] = 1.0
    E = expm(Ac * T)
    # discrete state after tick k: [x, x', ie, tau] at t_k, r_k, r_k-1, x_k-1

    def step(state, r_new):
        w_old = state[:ir]
        r, r_old, x_old = state[ir], state[ir + 1], state[ir + 2:]
        x = w_old[:n]
        rate = (r_new - r) / T
        w = E @ np.r_[w_old, r, rate]
        # the torque sampled at t_k-1 (the measured current), with that tick's setpoint rate
        sampled = torque @ np.r_[w_old, r, (r - r_old) / T]
        acc_hat = (w[:n] - 2 * x + x_old) / T**2
        vel_hat = (w[:n] - x_old) / (2 * T)
        out = dq @ (sampled - loop.mass @ acc_hat - loop.friction * vel_hat)   # u^T J^-T (torque)
        return np.r_[w[:ir], r_new, r, x], out

    total = ir + 2 + n
    cols = [step(e, 0.0) for e in np.eye(total)]
    A = np.column_stack([c[0] for c in cols])
    C = np.array([c[1] for c in cols])
    B, D = step(np.zeros(total), 1.0)
    return A, B, C, float(D)


def _response(A, B, C, D, z):
    n = A.shape[0]
    return np.array([C @ np.linalg.solve(zi * np.eye(n) - A, B) + D for zi in z])


def open_loop(loop: TangentLoop, stiffness: float, admittance: float, frequencies_hz: np.ndarray,
              force_filter: ForceFilter | None = None) -> np.ndarray:
    """L(e^{j w T}) at the given frequencies (Hz, below Nyquist): regulator x filter x plant."""
    T = loop.period
    z = np.exp(1j * 2 * np.pi * np.asarray(frequencies_hz, float) * T)
    P = _response(*plant_map(loop, stiffness), z)
    H = force_filter.response(z) if force_filter is not None else 1.0
    return T * admittance / (z - 1.0) * H * P * z ** (-loop.delay)


def closed_loop_matrix(loop: TangentLoop, stiffness: float, admittance: float,
                       force_filter: ForceFilter | None = None) -> np.ndarray:
    """Transition matrix of the closed loop (plant, filter, regulator) with f_des = 0."""
    A, B, C, D = plant_map(loop, stiffness)
    Af, Bf, Cf, Df = _delayed_filter(loop.delay, force_filter)
    nf, T, a = Af.shape[0], loop.period, admittance
    # state [plant (holds r_k), filter, y_k]: y_k is the filtered estimate the next tick reads
    n_joints = loop.direction.size
    npl = A.shape[0]
    npl_r = 3 * n_joints + (n_joints if loop.current_bandwidth is not None else 0)   # where r_k sits
    n = npl + nf + 1

    def step(s):
        p, f, y = s[:npl], s[npl:npl + nf], s[-1]
        r_next = p[npl_r] - T * a * y
        fhat = C @ p + D * r_next
        return np.r_[A @ p + B * r_next, Af @ f + Bf * fhat, Cf @ f + Df * fhat]
    return np.column_stack([step(e) for e in np.eye(n)])


def _delayed_filter(delay: int, force_filter: ForceFilter | None):
    """(A, B, C, D) of the sensor delay (a shift register of `delay` ticks) followed by the filter."""
    if force_filter is not None:
        Af, Bf, Cf, Df = force_filter.state_space()
    else:
        Af, Bf, Cf, Df = np.zeros((0, 0)), np.zeros(0), np.zeros(0), 1.0
    if delay == 0:
        return Af, Bf, Cf, Df
    nf = Af.shape[0]
    Ad = np.eye(delay, k=-1)
    A = np.zeros((delay + nf, delay + nf))
    A[:delay, :delay] = Ad
    A[delay:, delay - 1] = Bf
    A[delay:, delay:] = Af
    B = np.r_[1.0, np.zeros(delay - 1 + nf)]
    C = np.r_[np.zeros(delay - 1), Df, Cf]
    return A, B, C, 0.0


def _grid(loop: TangentLoop, points: int) -> np.ndarray:
    nyquist = 0.5 / loop.period
    return np.geomspace(1e-5 * nyquist, nyquist * (1 - 1e-9), points)


def _margins_of(f: np.ndarray, L: np.ndarray) -> tuple[float, float, float, float]:
    """(gain margin, phase margin deg, crossover Hz, phase crossover Hz) of a sampled open loop."""
    mag, phase = np.abs(L), np.unwrap(np.angle(L))
    cross = np.nonzero((mag[:-1] >= 1.0) & (mag[1:] < 1.0))[0]
    # no crossing: |L| < 1 everywhere on the grid (margin unbounded) or > 1 up to Nyquist (undefined)
    pm, fc = (np.inf, 0.0) if mag[-1] < 1.0 else (np.nan, float(f[-1]))
    if cross.size:
        i = cross[-1]
        t = -np.log(mag[i]) / (np.log(mag[i + 1]) - np.log(mag[i]))
        pm = 180.0 + np.degrees(phase[i] + t * (phase[i + 1] - phase[i]))
        fc = float(f[i] * (f[i + 1] / f[i]) ** t)
    # the loop meets the negative real axis wherever the phase passes -180 deg + k 360 deg (a delay's phase
    # keeps falling past -540 deg towards Nyquist); the gain that first reaches -1 is set by the largest |L|
    # there. The grid's last point sits just below Nyquist, where L is real: a phase within 1e-6 rad of an
    # odd multiple of pi there counts as a crossing too.
    turn = np.floor((phase + np.pi) / (2 * np.pi))
    gm, fp = np.inf, float(f[-1])
    crossings = []
    for i in np.nonzero(turn[1:] != turn[:-1])[0]:
        target = -np.pi + 2 * np.pi * max(turn[i], turn[i + 1])
        t = (target - phase[i]) / (phase[i + 1] - phase[i])
        crossings.append((float(np.exp(np.log(mag[i]) + t * (np.log(mag[i + 1]) - np.log(mag[i])))),
                          float(f[i] + t * (f[i + 1] - f[i]))))
    odd = np.round((phase[-1] + np.pi) / (2 * np.pi))
    if abs(phase[-1] + np.pi - 2 * np.pi * odd) < 1e-6 and not (crossings and crossings[-1][1] == f[-1]):
        crossings.append((float(mag[-1]), float(f[-1])))
    if crossings:
        top, fp = max(crossings)
        gm = 1.0 / top
    return float(gm), float(pm), float(fc), fp


def margins(loop: TangentLoop, stiffness: float, admittance: float, force_filter: ForceFilter | None = None,
            points: int = 2000) -> Margins:
    """Gain and phase margins of the force loop against a contact of `stiffness` N/m, and the
    closed-loop stability from the eigenvalues (which also covers several crossings)."""
    if not (stiffness > 0 and admittance > 0):
        raise InputError("contact stiffness and admittance must be > 0", field="stiffness")
    f = _grid(loop, points)
    gm, pm, fc, fp = _margins_of(f, open_loop(loop, stiffness, admittance, f, force_filter))
    rho = float(np.max(np.abs(np.linalg.eigvals(closed_loop_matrix(loop, stiffness, admittance,
                                                                    force_filter)))))
    return Margins(gm, pm, fc, fp, rho < 1.0, rho)


def admittance_for_margins(loop: TangentLoop, max_stiffness: float, force_filter: ForceFilter | None = None,
                           phase_margin: float = 45.0, gain_margin: float = 2.0, min_stiffness: float | None = None,
                           samples: int = 5, points: int = 1500) -> float:
    """Largest admittance m/(N s) whose loop keeps both margins for every contact stiffness in
    [min_stiffness, max_stiffness] (log-spaced samples; min defaults to max/100).

    The open loop is proportional to the admittance, so each stiffness's response is computed once
    and the admittance scanned on a log grid from 1 m/(N s) down, then refined by bisection; the
    result is checked for closed-loop stability at every sampled stiffness."""
    lo_k = max_stiffness / 100.0 if min_stiffness is None else min_stiffness
    if not 0 < lo_k <= max_stiffness:
        raise InputError(f"stiffness range must satisfy 0 < min <= max, got {lo_k:g}, {max_stiffness:g}",
                         field="stiffness")
    f = _grid(loop, points)
    unit = [open_loop(loop, k, 1.0, f, force_filter) for k in np.geomspace(lo_k, max_stiffness, samples)]

    def ok(a):
        for L in unit:
            gm, pm, *_ = _margins_of(f, a * L)
            if not (gm >= gain_margin and pm >= phase_margin):
                return False
        return True
    # the phase margin is not monotonic in the admittance (the servo's integral action bends the
    # phase at low frequency against stiff contacts): scan down from 1 m/(N s), then refine
    grid = np.geomspace(1.0, 1e-8, 321)
    good = [i for i, a in enumerate(grid) if ok(a)]
    if not good:
        raise InputError(f"no admittance keeps {phase_margin} deg and x{gain_margin} margins up to "
                         f"{max_stiffness:g} N/m", field="stiffness")
    lo = grid[good[0]]
    hi = grid[good[0] - 1] if good[0] > 0 else lo
    for _ in range(30 if hi > lo else 0):
        mid = np.sqrt(lo * hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    for k in np.geomspace(lo_k, max_stiffness, samples):
        if not margins(loop, k, lo, force_filter, points=points).stable:
            raise InputError(f"admittance {lo:.3g} meets the margins but the loop is unstable at {k:g} N/m",
                             field="stiffness")
    return float(lo)
