"""Simulated motor-side logs: what a controller records of a robot driven through a transmission, for
synthetic-truth tests and the examples (examples/motor_dynamics/make_logs.py, docs/dynamics_motors.md).

A smooth excitation (sums of sines inside each joint's range) gives exact q, v, a; the truth robot's RNEA
gives the joint torques; the motors deliver tau_m = T^T tau + J mddot + Fc tanh(mdot / eps) + Fv mdot + tau0
(channels.py's model, with eps = coulomb_width x each motor's RMS speed over the training window, the
identification's rule); the log holds the motor encoder positions m = T^-1 (q - c), quantised to the
encoder's counts, and the currents tau_m / K with white noise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.dynamics.inertial import parameter_vector, with_parameters
from robocal.dynamics.transmission import Transmission


@dataclass
class MotorTerms:
    """Per motor (transmission order): rotor_inertia (kg m^2), coulomb (N m), viscous (N m s/rad), offset (N m)."""

    rotor_inertia: np.ndarray
    coulomb: np.ndarray
    viscous: np.ndarray
    offset: np.ndarray

    def values(self, kind: str) -> np.ndarray:
        return np.asarray({"armature": self.rotor_inertia, "coulomb": self.coulomb, "viscous": self.viscous,
                           "offset": self.offset}[kind], float)


def excitation(t: np.ndarray, model: pin.Model, seed: int, frequencies=(0.15, 0.3, 0.5),
               max_amplitude: float = 0.8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact q, v, a (T, nv): per joint a sum of sines (frequencies +-20 %, random phases) around the middle
    of its range, of total amplitude min(max_amplitude, a quarter of the range)."""
    rng = np.random.default_rng(seed)
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    q, v, a = (np.zeros((len(t), model.nv)) for _ in range(3))
    for j in range(model.nv):
        amp = min(max_amplitude, 0.25 * (hi[j] - lo[j])) * rng.dirichlet(np.ones(len(frequencies)))
        for A, f in zip(amp, frequencies):
            w, ph = 2 * np.pi * f * (1 + 0.2 * rng.uniform(-1, 1)), rng.uniform(0, 2 * np.pi)
            q[:, j] += A * np.sin(w * t + ph)
            v[:, j] += A * w * np.cos(w * t + ph)
            a[:, j] -= A * w ** 2 * np.sin(w * t + ph)
        q[:, j] += (lo[j] + hi[j]) / 2
    return q, v, a


def perturbed_model(model: pin.Model, seed: int) -> pin.Model:
    """The model with a random 0.1-0.3 kg point mass added to each body (a realisable truth unlike the CAD)."""
    rng = np.random.default_rng(seed)
    params = parameter_vector(model).reshape(-1, 10).copy()
    for p in params:
        m, r = rng.uniform(0.1, 0.3), rng.normal(0, 0.05, 3)
        inertia = m * (r @ r * np.eye(3) - np.outer(r, r))
        p += np.r_[m, m * r, inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2], inertia[1, 2], inertia[2, 2]]
    return with_parameters(model, params.reshape(-1))


def motor_torques(truth: pin.Model, transmission: Transmission, terms: MotorTerms, q: np.ndarray, v: np.ndarray,
                  a: np.ndarray, width: np.ndarray) -> np.ndarray:
    """(T, n) motor torques (transmission order) of the truth robot; q, v, a in the transmission's joint order
    (the model's own when they agree); width: the Coulomb tanh width per motor (rad/s)."""
    data = truth.createData()
    tau = np.array([pin.rnea(truth, data, q[k], v[k], a[k]) for k in range(len(q))])
    md, mdd = transmission.motor_rates(v), transmission.motor_rates(a)
    return (tau @ transmission.matrix + terms.rotor_inertia * mdd + terms.coulomb * np.tanh(md / width)
            + terms.viscous * md + terms.offset)


def coulomb_widths(transmission: Transmission, v: np.ndarray, in_train: np.ndarray, fraction: float) -> np.ndarray:
    """The identification's rule on the exact speeds: fraction x each motor's RMS speed over the training rows."""
    return fraction * np.sqrt(np.mean(transmission.motor_rates(v[in_train]) ** 2, axis=0))


def logged_signals(transmission: Transmission, q: np.ndarray, tau_m: np.ndarray, counts_per_rev: int,
                   current_noise: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(encoder positions quantised to 2 pi / counts_per_rev, currents tau_m / K with white noise (A))."""
    step = 2 * np.pi / counts_per_rev
    m = np.round(transmission.motor_positions(q) / step) * step
    current = tau_m / transmission.motor_constant + rng.normal(size=tau_m.shape) * current_noise
    return m, current
