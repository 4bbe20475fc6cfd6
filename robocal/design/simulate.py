"""Synthetic truth: perturb a robot's parameters, pick configurations, make noisy measurements.

Observed measurement types (pose, point, ball bar, ...) are simulated by predicting the measured
quantity on the true robot and adding Gaussian noise of the residual's sigma. Contact types (plane,
sphere, cylinder, laser line) have no measured quantity: the robot is moved (Gauss-Newton on the read
joints from the given configuration) until the true constraint holds up to a Gaussian error of the
residual's sigma, which is how a touch-trigger probe's scatter shows up in the readings.
"""
from __future__ import annotations

import fnmatch

import numpy as np

from robocal.errors import RobocalError
from robocal.model.parameters import ParameterSet
from robocal.estimation.problem import Problem


def perturb(params: ParameterSet, rng: np.random.Generator, translation: float = 2e-3,
            rotation: float = np.radians(0.2), patterns: list[str] | None = None,
            include_fixed: bool = False) -> ParameterSet:
    """A copy with robot parameters drawn uniformly in +-translation (m) / +-rotation (rad).

    Only free parameters (or all, with include_fixed) matching `patterns` are perturbed; auxiliary
    parameters (the measurement set-up) are left as they are.
    """
    truth = params.copy()
    for p in truth:
        if p.kind == "auxiliary" or not (p.vary or include_fixed):
            continue
        if patterns and not any(fnmatch.fnmatchcase(p.name, pat) for pat in patterns):
            continue
        a = translation if p.unit == "m" else rotation
        p.value = p.value + rng.uniform(-a, a)
    return truth


def random_configurations(robot, joint_names: list[str], n: int, rng: np.random.Generator,
                          margin: float = 0.05, span: float = 1.0) -> np.ndarray:
    """(n, len(joint_names)) uniform within the joint limits (shrunk by `margin`, scaled by `span`)."""
    lo, hi = robot.limits(joint_names)
    mid, half = (lo + hi) / 2, (hi - lo) / 2 * (1 - margin) * span
    return rng.uniform(mid - half, mid + half, (n, len(joint_names)))


def simulate_measurements(problem: Problem, truth: ParameterSet, rng: np.random.Generator,
                          max_iterations: int = 100, skip_unreachable: bool = False) -> set[int]:
    """Fill `problem`'s measurements (and, for contact types, its joint readings) from `truth`.

    Contact-type residuals must own their samples (no other residual may use them). A contact the robot
    cannot reach from a sample's readings raises, or with skip_unreachable=True leaves that sample as it
    was; the samples left so are returned.
    """
    unreachable: set[int] = set()
    saved = problem.params
    problem.params = truth
    try:
        ms = problem.model_state()
        states = problem.states(ms)
        for res in problem.residuals:
            aux = problem.aux_values(res)
            if res.observed:
                res_rows = [res.simulate(k, states, aux, rng) for k in range(res.n_terms)]
                if hasattr(res, "set_measurements"):
                    res.set_measurements(np.array(res_rows))
                else:
                    res.measurements = np.array(res_rows)
            else:
                for k in range(res.n_terms):
                    if len(res.term_samples(k)) != 1:
                        raise RobocalError(f"simulation: '{res.name}' has terms over several samples; simulate "
                                           "its acquisition with its own model (e.g. robocal.systems.pcmm.machine)")
                    i = int(res.samples[k])
                    try:
                        problem.values[i] = within_turns(problem, _project(res, k, ms, problem.values[i], aux, rng,
                                                                           max_iterations))
                    except RobocalError:
                        if not skip_unreachable:
                            raise
                        unreachable.add(i)
    finally:
        problem.params = saved
    return unreachable


def within_turns(problem: Problem, values: np.ndarray) -> np.ndarray:
    """Revolute readings moved by whole turns into their URDF limits where that brings them in: the same pose,
    read as the robot reports it (a projection onto a contact does not know the limits)."""
    model, out = problem.robot.model, np.array(values, dtype=float)
    for c, name in enumerate(problem.joint_names):
        jm = model.joints[problem.robot.joint_id(name)]
        if jm.nq != 1 or not jm.shortname().startswith("JointModelR"):
            continue
        lo, hi = model.lowerPositionLimit[jm.idx_q], model.upperPositionLimit[jm.idx_q]
        turned = out[c] - 2 * np.pi * np.floor((out[c] - lo) / (2 * np.pi))      # into [lo, lo + 2 pi)
        if np.isfinite(lo) and np.isfinite(hi) and not lo <= out[c] <= hi and turned <= hi:
            out[c] = turned
    return out


def _project(res, k, ms, values, aux, rng, max_iterations, max_step=0.3):
    """Move the read joints until residual term k equals a noise draw.

    Min-norm Gauss-Newton on the joints, each step limited to `max_step` rad and halved while it does
    not reduce the error (contacts far from the start would otherwise overshoot).
    """
    target = rng.normal(0.0, res.sigma)
    i = int(res.samples[k])

    def error(v):
        s = ms.sample(v)
        t = res.evaluate(k, {i: s}, aux)
        return t.r - target, t, s

    err, t, s = error(values.copy())
    values = values.copy()
    for _ in range(max_iterations):
        if np.max(np.abs(err)) < 1e-13:
            return values
        Jq = sum(D @ s.frame_joint_jacobian(f) for _, f, D in t.frames)
        dq = -np.linalg.lstsq(Jq, err, rcond=None)[0]
        dq *= min(1.0, max_step / max(np.max(np.abs(dq)), 1e-300))
        for _ in range(30):
            trial = error(values + dq)
            if np.linalg.norm(trial[0]) < np.linalg.norm(err):
                break
            dq /= 2
        values = values + dq
        err, t, s = trial
    raise RobocalError(f"simulation: could not bring sample {i} onto '{res.name}' (unreachable contact?)")
