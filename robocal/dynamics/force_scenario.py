"""The deburring scenario under realistic conditions: a servoed arm with stick-slip joints, noisy
currents and a sensor delay, pushing along a line into a wall; the estimator's model given with
an error or identified from simulated excitation data; one run summarised as the issue's table asks.

Used by examples/force_deburring.py, benchmarks/force_regulation_realism.py and the tests, so all
three run the same plant. Figures and their conditions: docs/dynamics.md, "Under stiction".
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.contact_observer import ContactForceObserver, ObserverSettings
from robocal.dynamics.current_force_loop import CurrentForceLoop
from robocal.dynamics.differentiation import TickDifferentiator, differentiate
from robocal.dynamics.environment import Environment, Wall
from robocal.dynamics.excitation import fourier_excitation
from robocal.dynamics.external_force import ExternalForceEstimator
from robocal.dynamics.friction import FrictionModel
from robocal.dynamics.generator import PathGenerator
from robocal.dynamics.identification import Segment, identify_dynamics
from robocal.dynamics.instructions import MotionParams, movelf
from robocal.dynamics.simulator import RobotSimulator
from robocal.dynamics.stick_slip import StickSlipFriction


@dataclass
class Plant:
    """The simulated robot: model, tool frame, start pose q0, actuator, friction (stick-slip), servo
    gains, period s, current noise A, measurement delay ticks."""

    model: pin.Model
    frame_id: int
    q0: np.ndarray
    actuator: ActuatorModel
    friction: StickSlipFriction
    gains: tuple
    period: float = 0.004
    current_noise: float = 0.005
    delay: int = 1

    def simulator(self, environment, seed: int = 1) -> RobotSimulator:
        return RobotSimulator(self.model, self.frame_id, self.q0, self.actuator, self.friction, environment,
                              self.gains, self.period, current_noise=self.current_noise, seed=seed,
                              measurement_delay=self.delay)


@dataclass
class RunSummary:
    """Steady contact (the last `window` ticks): true force min/max N, force for the regulator min/max,
    path speed peak to peak mm/s; free space: mean force for the regulator (bias) N and mean feed
    speed mm/s; peak: the largest true force of the run N; command_force: the wall's force at the last
    commanded tool position N (what the force would be with the servos on their set-point: the true
    force minus it is the servos' offset); observer: the ContactForceObserver (None for the former
    design); rows (ticks, 3): [force for the regulator, feed speed mm/s, true tangential force]."""

    true_band: tuple[float, float]
    estimate_band: tuple[float, float]
    speed_ripple: float
    free_bias: float
    feed_speed: float
    peak: float
    command_force: float
    observer: ContactForceObserver | None
    rows: np.ndarray


def scaled_friction(friction: StickSlipFriction, factor: float) -> FrictionModel:
    """The estimator's friction model with every level off by `factor` (Coulomb, breakaway excess, viscous)."""
    return FrictionModel(factor * friction.coulomb, factor * friction.viscous, factor * friction.offset,
                         factor * (friction.breakaway - friction.coulomb), friction.stribeck_velocity, 1e-3)


def scaled_actuator(actuator: ActuatorModel, factor: float) -> ActuatorModel:
    """The estimator's actuator with the torque constants off by `factor`."""
    return ActuatorModel(factor * actuator.torque_constant, actuator.gear_ratio, actuator.current_offset,
                         actuator.coupling)


def excitation_segment(plant: Plant, seconds: float = 10.0, seed: int = 0, amplitude: float = 0.3) -> Segment:
    """A Fourier excitation (one 0.1 Hz period, 5 harmonics, +-`amplitude` rad about q0, joint speeds up to
    1 rad/s) run on the simulated plant in free space: the measured (delayed, noisy) positions, their
    central differences and the measured currents, as a `Segment` for `identify_dynamics`."""
    m, ts = plant.model, plant.period
    rng = np.random.default_rng(seed)
    n = m.nv
    traj = fourier_excitation(plant.q0 - amplitude, plant.q0 + amplitude, np.full(n, 1.0), np.full(n, 3.0), rng,
                              base_frequency=1.0 / seconds, margin=0.0, centre=plant.q0)
    t = np.arange(int(round(seconds / ts)) + 1) * ts
    q_des = traj.sample(t)[0]
    sim = plant.simulator(Environment(), seed=seed + 1)
    # the servo starts holding q0; the excitation starts there with a non-zero speed, so skip the first second
    logs = [sim.step(q) for q in np.vstack([np.repeat(q_des[:1], 25, axis=0), q_des])]
    q = np.array([r.q_mes for r in logs])[25 + int(1.0 / ts):]
    current = np.array([r.current for r in logs])[25 + int(1.0 / ts):]
    v, a = differentiate(q, ts, "central")
    keep = slice(2, -2)
    return Segment(q[keep], v[keep], a[keep], current[keep])


def identify_friction(plant: Plant, seconds: float = 10.0, seed: int = 0, amplitude: float = 0.3):
    """Identify the plant's dynamics from `excitation_segment` with `identify_dynamics` (Coulomb, viscous,
    offset; the torque-constant scale is not observable without a payload and stays nominal).
    Returns the DynamicIdentificationResult."""
    template = FrictionModel(np.zeros(plant.model.nv), smoothing=1e-3)
    return identify_dynamics(plant.model, [excitation_segment(plant, seconds, seed, amplitude)], plant.actuator,
                             template, current_noise=plant.current_noise)


def deburr(plant: Plant, estimator_friction: FrictionModel, estimator_actuator: ActuatorModel | None = None,
           admittance: float = 7.58e-4, filter_hz: float | None = 10.0, observer: bool = True,
           settings: ObserverSettings | None = None, wall_at: float = 0.03, stiffness: float = 2e4,
           force: float = 20.0, ticks: int = 1500, window: int = 250, model: pin.Model | None = None,
           seed: int = 1) -> RunSummary:
    """Push along +x towards a wall `wall_at` m ahead with `force` N; observer=False is the former design
    (raw current-based estimate, low-passed at filter_hz in the path generator); with the observer the
    filter acts on its raw values only (ObserverSettings.filter_hz), not on the contact line.
    model: the estimator's dynamic model (the plant's by default)."""
    m, fid = plant.model, plant.frame_id
    data = m.createData()
    pin.framesForwardKinematics(m, data, plant.q0)
    start = data.oMf[fid].copy()
    along = np.array([1.0, 0.0, 0.0])
    sim = plant.simulator(Environment(Wall(start.translation + wall_at * along, along, stiffness)), seed)
    if observer:
        settings = replace(settings or ObserverSettings(), filter_hz=filter_hz)
    ins = movelf(m, fid, plant.q0, pin.SE3(start.rotation, start.translation + 0.2 * along),
                 MotionParams(0.25, 1.0, admittance=admittance, force_filter_hz=None if observer else filter_hz),
                 force)
    estimator = ExternalForceEstimator(model or m, fid, estimator_actuator or plant.actuator, estimator_friction)
    loop = CurrentForceLoop(PathGenerator(m, ins, plant.period), sim, estimator,
                            TickDifferentiator(plant.period, "central"),
                            ContactForceObserver(force, settings, plant.period) if observer else None)
    rows = []
    for _ in range(ticks):
        sp, meas = loop.tick()
        rows.append([sp.force, sp.sd * ins.path.length * 1e3, meas.true_wrench[:3] @ along])
    rows = np.array(rows)
    pin.framesForwardKinematics(m, data, loop.generator.q_des)
    command_force = float(sim.environment.wrench(data.oMf[fid].translation, np.zeros(3))[:3] @ along)
    tail = rows[-window:]
    touching = np.nonzero(rows[:, 2] > 0)[0]
    first = touching[0] if touching.size else ticks
    free = rows[first // 3: max(first - 25, first // 3 + 1)]          # steady free-space approach
    return RunSummary((tail[:, 2].min(), tail[:, 2].max()), (tail[:, 0].min(), tail[:, 0].max()),
                      float(np.ptp(tail[:, 1])), float(free[:, 0].mean()), float(free[:, 1].mean()),
                      float(rows[:, 2].max()), command_force, loop.observer, rows)
