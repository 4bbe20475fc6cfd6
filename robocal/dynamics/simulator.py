"""A servo-controlled robot for tests and examples (spec §11.2 item 12): Pinocchio forward dynamics
(aba) with per-joint PID position servos (Fig. 5), an ideal or first-order current loop, friction, a
contact environment, and measured currents synthesised with noise and quantisation.

Each control period (4 ms) the servo receives q_des and interpolates it linearly from the previous
setpoint over `substeps` integration steps (semi-implicit Euler), as industrial drives do, so the
motion and the currents stay smooth. The PID acts in joint-torque units and the actuator model turns
its output into current setpoints: I_des = actuator.current(Kp e + Ki int e + Kd de/dt). With
`current_bandwidth` w_c (rad/s) the motor current follows I_des as a first-order lag (exact over each
substep) and the measured current is that lagging current; without it I = I_des.

Accuracy: semi-implicit Euler is first order in the substep. Against the exact response of the
linearised arm (force_loop.py), the current-based force one tick after a setpoint step is 35 % too
large with the default 4 substeps, 8 % with 16, 2 % with 64 (tests/test_dynamics_force_loop.py);
the default simulator therefore rings a little earlier than the real (continuous) arm would.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.friction import FrictionModel
from robocal.dynamics.stick_slip import StickSlipFriction

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def servo_gains(model: pin.Model, q: np.ndarray, bandwidth: float = 60.0, damping_ratio: float = 0.9,
                integral_ratio: float = 0.1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """PID gains (kp N m/rad, ki N m/(rad s), kd N m s/rad) placing each joint's closed loop at
    `bandwidth` rad/s for the joint's own inertia (diagonal of M(q) plus armature)."""
    inertia = np.diag(pin.crba(model, model.createData(), q)).copy()
    kp = inertia * bandwidth**2
    kd = 2 * damping_ratio * inertia * bandwidth
    return kp, integral_ratio * bandwidth * kp, kd


@dataclass
class TickMeasurement:
    """What the controller reads at the end of a period: q_mes (nq,), v_mes (nv,) (the drive's
    velocity sensor), current (nv,) A measured, current_des (nv,) A commanded, and the true contact
    wrench (6,) for checking."""

    q_mes: np.ndarray
    v_mes: np.ndarray
    current: np.ndarray
    current_des: np.ndarray
    true_wrench: np.ndarray


class RobotSimulator:
    """model, frame_id (the TCP where the environment acts), actuator, friction, environment (with
    `wrench(x, v)`), gains (kp, ki, kd) per joint, period s, substeps per period, current_noise A
    (std of measured currents), quantisation A (current LSB, 0 = none), seed, current_bandwidth
    rad/s of a first-order current loop (None: ideal), measurement_delay ticks (the controller reads
    the positions and currents of that many periods ago; 0: the end of this period). friction may
    be a `StickSlipFriction` (joints stick at rest; solved implicitly per substep)."""

    def __init__(self, model: pin.Model, frame_id: int, q0: np.ndarray, actuator: ActuatorModel,
                 friction: FrictionModel, environment, gains, period: float = 0.004, substeps: int = 4,
                 current_noise: float | np.ndarray = 0.0, quantisation: float = 0.0, seed: int = 0,
                 current_bandwidth: float | None = None, measurement_delay: int = 0):
        if measurement_delay < 0:
            raise InputError(f"measurement delay must be >= 0 ticks, got {measurement_delay}",
                             field="measurement_delay")
        if substeps < 1 or not period > 0:
            raise InputError("simulator needs period > 0 and substeps >= 1", field="substeps")
        if current_bandwidth is not None and not current_bandwidth > 0:
            raise InputError(f"current-loop bandwidth must be > 0 rad/s, got {current_bandwidth}",
                             field="current_bandwidth")
        self.model, self.data, self.frame_id = model, model.createData(), frame_id
        self.actuator, self.friction, self.environment = actuator, friction, environment
        self.kp, self.ki, self.kd = (np.asarray(g, float) for g in gains)
        self.period, self.substeps, self.dt = period, substeps, period / substeps
        self.noise, self.lsb = current_noise, quantisation
        self.rng = np.random.default_rng(seed)
        self.q = np.array(q0, float)
        self.v = np.zeros(model.nv)
        self.q_des_prev = self.q.copy()
        # the servo has been holding q0: its integrator carries gravity
        self.integral = pin.rnea(model, self.data, self.q, self.v, self.v) / np.where(self.ki > 0, self.ki, 1.0)
        self.integral[self.ki == 0] = 0.0
        # first-order current loop: the fraction of the error removed per substep (exact for a held command)
        self.current_step = None if current_bandwidth is None else 1.0 - np.exp(-current_bandwidth * self.dt)
        self.current = actuator.current(pin.rnea(model, self.data, self.q, self.v, self.v))
        self._fext = pin.StdVec_Force()
        for _ in range(model.njoints):
            self._fext.append(pin.Force.Zero())
        self.time = 0.0
        self.delay = int(measurement_delay)
        x0, _ = self.tcp_state()         # before the first period the sensors read the initial rest state
        rest = TickMeasurement(self.q.copy(), self.v.copy(), self.current.copy(), self.current.copy(),
                               self.environment.wrench(x0, np.zeros(3)))
        self._pending = [rest] * self.delay

    def tcp_state(self) -> tuple[np.ndarray, np.ndarray]:
        """TCP position (3,) m and linear velocity (3,) m/s, world."""
        m, d = self.model, self.data
        pin.forwardKinematics(m, d, self.q, self.v)
        pin.updateFramePlacement(m, d, self.frame_id)
        return d.oMf[self.frame_id].translation.copy(), pin.getFrameVelocity(m, d, self.frame_id, _LWA).linear.copy()

    def _servo(self, target: np.ndarray, v_ff: np.ndarray, advance: bool) -> np.ndarray:
        err = pin.difference(self.model, self.q, target)
        if advance:
            self.integral += err * self.dt
        tau_cmd = self.kp * err + self.ki * self.integral + self.kd * (v_ff - self.v)
        return self.actuator.current(tau_cmd)

    def step(self, q_des: np.ndarray) -> TickMeasurement:
        """Run one control period towards the new setpoint; return the end-of-period measurements."""
        m, d = self.model, self.data
        q_des = np.asarray(q_des, float)
        v_ff = pin.difference(m, self.q_des_prev, q_des) / self.period
        for k in range(1, self.substeps + 1):
            target = pin.integrate(m, self.q_des_prev, v_ff * (k * self.dt))
            current_des = self._servo(target, v_ff, advance=True)
            if self.current_step is None:
                self.current = current_des                           # ideal current loop: I = I_des
            else:
                self.current = self.current + self.current_step * (current_des - self.current)
            x, xd = self.tcp_state()
            wrench = self.environment.wrench(x, xd)
            joint = m.frames[self.frame_id].parentJoint
            world = pin.SE3(np.eye(3), x).act(pin.Force(-wrench))   # environment on robot
            self._fext[joint] = d.oMi[joint].actInv(world)
            if isinstance(self.friction, StickSlipFriction):
                tau = self.actuator.torque(self.current) - self.friction.smooth_part(self.v)
                v_free = self.v + self.dt * pin.aba(m, d, self.q, self.v, tau, self._fext)
                mass = pin.crba(m, d, self.q)
                mass = np.triu(mass) + np.triu(mass, 1).T
                self.v = self.friction.implicit_velocity(mass, v_free, self.v, self.dt)
            else:
                tau = self.actuator.torque(self.current) - self.friction.torque(self.v)
                self.v = self.v + self.dt * pin.aba(m, d, self.q, self.v, tau, self._fext)
            self.q = pin.integrate(m, self.q, self.v * self.dt)
            self.time += self.dt
        self.q_des_prev = q_des.copy()
        current_des = self._servo(q_des, v_ff, advance=False)   # sampled with the end-of-period state
        actual = current_des if self.current_step is None else self.current
        measured = actual + self.rng.normal(size=m.nv) * self.noise
        if self.lsb > 0:
            measured = np.round(measured / self.lsb) * self.lsb
        x, xd = self.tcp_state()
        now = TickMeasurement(self.q.copy(), self.v.copy(), measured, current_des.copy(),
                              self.environment.wrench(x, xd))
        if not self.delay:
            return now
        # the sensors' samples reach the controller `delay` ticks late; true_wrench stays current
        self._pending.append(now)
        old = self._pending.pop(0)
        return TickMeasurement(old.q_mes, old.v_mes, old.current, old.current_des, now.true_wrench)
