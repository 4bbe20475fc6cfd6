"""Synthetic TIAGo joint logs with the shipped log's time stamps and noise levels, written as the
three CSV files the identification config reads (shared by the tests/test_dynamics_tiago_* files)."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml
from scipy.signal import butter, sosfiltfilt

from robocal.dynamics.reduced_model import reduced_model
from robocal.dynamics.motor_simulation import perturbed_model

EXAMPLE = Path(__file__).resolve().parents[1] / "examples/tiago_dynamics"
CONFIG = EXAMPLE / "identify.yaml"
JOINTS = ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)]
RECORDED = JOINTS[:5]
KINDS = ("position", "velocity", "effort")
#: (coulomb, viscous, offset, armature) per recorded joint, of the size identified on the real log
TRUE_EXTRA = np.array([[0.8, 0.1, 2.0, 0.5], [2.5, 25.0, 0.15, 1.5], [5.0, 8.0, -0.6, 0.4],
                       [2.6, 5.6, 0.0, 0.3], [2.0, 5.7, 0.1, 0.1]])


def shipped(kind: str) -> np.ndarray:
    return np.genfromtxt(EXAMPLE / "data" / f"tiago_{kind}.csv", delimiter=",", skip_header=1)


def base_config() -> dict:
    return yaml.safe_load(CONFIG.read_text())


def split_config(train, validate) -> dict:
    """The shipped config with its log's windows replaced (validate None: training only)."""
    cfg = copy.deepcopy(base_config())
    cfg["logs"][0]["train"] = list(train)
    if validate is None:
        cfg["logs"][0].pop("validate", None)
    else:
        cfg["logs"][0]["validate"] = list(validate)
    return cfg


def urdf_path() -> Path:
    return (CONFIG.parent / base_config()["robot"]["urdf"]).resolve()


def log_noise(kind: str, cutoff_hz: float = 3.4) -> np.ndarray:
    """Per-joint RMS of the shipped log's content above `cutoff_hz` (its noise level), on a uniform
    100 Hz grid (the log's median rate)."""
    data = shipped(kind)
    t = data[:, 0]
    grid = np.arange(t[0], t[-1], 0.01)
    x = np.column_stack([np.interp(grid, t, data[:, j]) for j in range(1, data.shape[1])])
    sos = butter(4, cutoff_hz, fs=100.0, output="sos")
    return np.sqrt(np.mean((x - sosfiltfilt(sos, x, axis=0)) ** 2, axis=0))


def trajectory(t: np.ndarray, model: pin.Model, seed: int, frequencies=(0.07, 0.13, 0.23)):
    """Sum of sines per joint inside 25-75 % of its range; exact q, v, a (T, 8)."""
    rng = np.random.default_rng(seed)
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    q, v, a = (np.zeros((len(t), model.nv)) for _ in range(3))
    for j in range(model.nv):
        amp = 0.5 * half[j] * rng.dirichlet(np.ones(len(frequencies)))
        phase = rng.uniform(0, 2 * np.pi, len(frequencies))
        for A, f, ph in zip(amp, frequencies, phase):
            w = 2 * np.pi * f * (1 + 0.2 * rng.uniform(-1, 1))
            q[:, j] += A * np.sin(w * t + ph)
            v[:, j] += A * w * np.cos(w * t + ph)
            a[:, j] -= A * w**2 * np.sin(w * t + ph)
        q[:, j] += mid[j]
    return q, v, a


def synthetic_log(folder: Path, rows: int, train: tuple[float, float], validate: tuple[float, float],
                  seed: int = 0, noise: bool = True):
    """Write tiago_{position,velocity,effort}.csv into `folder` (the shipped log's first `rows` time
    stamps) and return (config dict with these windows, truth model, true extra terms (5, 4)).
    The truth's Coulomb tanh width follows the config's rule on the exact velocities."""
    cfg = split_config(train, validate)
    model = reduced_model(urdf_path(), JOINTS)
    t = shipped("position")[:rows, 0]
    q, v, a = trajectory(t, model, seed)
    truth = perturbed_model(model, seed + 1)
    data = truth.createData()
    tau = np.array([pin.rnea(truth, data, q[k], v[k], a[k]) for k in range(len(t))])[:, :5]
    in_train = (t >= train[0]) & (t < train[1])
    width = cfg["model"]["coulomb_width"] * np.sqrt(np.mean(v[in_train, :5] ** 2, axis=0))
    c, fv, off, arm = TRUE_EXTRA.T
    tau += c * np.tanh(v[:, :5] / width) + fv * v[:, :5] + off + arm * a[:, :5]
    eff = cfg["effort"]
    scale = np.array([eff["gear_ratio"][j] * eff["motor_constant"][j] for j in RECORDED])
    offset = np.array([eff["torque_offset"].get(j, 0.0) for j in RECORDED])
    effort = np.zeros((len(t), 8))
    effort[:, :5] = (tau - offset) / scale
    rng = np.random.default_rng(seed + 2)
    velocity = np.vstack([np.zeros((1, 8)), np.diff(q, axis=0) / np.diff(t)[:, None]])   # a crude logged velocity
    if noise:
        q = q + rng.normal(size=q.shape) * log_noise("position")
        effort[:, :5] += rng.normal(size=(len(t), 5)) * log_noise("effort")[:5]
    write_log(folder, t, {"position": q, "velocity": velocity, "effort": effort})
    for k in KINDS:
        cfg["logs"][0][k] = str(folder / f"tiago_{k}.csv")
    cfg["robot"]["urdf"] = str(urdf_path())
    # the logged velocities above are crude differences, half a step late: not lagging enough for the auto
    # rule to leave them (filtering.AUTO_LAG_STEPS), biased enough to tilt friction and inertia
    cfg["signal"]["velocity_source"] = "differentiated"
    cfg.pop("output", None)
    return cfg, truth, TRUE_EXTRA


def write_log(folder: Path, t: np.ndarray, values: dict[str, np.ndarray]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for kind in KINDS:
        header = "t," + ",".join(f"- {j}_{kind}" for j in JOINTS)
        np.savetxt(folder / f"tiago_{kind}.csv", np.column_stack([t, values[kind]]), delimiter=",",
                   header=header, comments="", fmt="%.17g")
