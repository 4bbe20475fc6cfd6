"""Motion instructions MOVEJF / MOVELF (spec §3, blocks 200-300) and their validation.

An instruction carries the path shape, the tangential-force setpoint f_des (N, the force the tool
should exert along the path) and the motion parameters. Everything is checked before execution:
finite f_des, v_max and a_max > 0, c in (0, 1), a non-degenerate path and, for Cartesian paths
(MOVELF, `movecf`), an inverse kinematics solution within the joint position limits all along the
path (so the setpoints cannot fail mid-motion; a path past a joint stop is refused, naming it).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.model.inverse_kinematics import IKFailure, solve_ik
from robocal.dynamics.joint_projection import check_position_limits
from robocal.dynamics.limits import check_c
from robocal.dynamics.path import CartesianPath, JointPath, LinearPath

log = logging.getLogger(__name__)


@dataclass
class MotionParams:
    """v_max m/s and a_max m/s^2 on the TCP translation; c in (0, 1) (Eq. 5); admittance m/(N s)
    sets the regulator gain K = admittance/|f'| (spec §13.14), or give `gain` K in 1/(N s) directly;
    blend: the motion continues into the next one (no braking at s = 1); joint limits optional
    (rad/s, rad/s^2 per velocity coordinate); force_filter_hz: cut-off of the second-order
    low-pass on the force estimate (None: the raw estimate, as in the patent); w_max rad/s and
    dw_max rad/s^2: optional limits on the tool's orientation rate along Cartesian paths. Choose the
    admittance and the filter together with `force_loop.admittance_for_margins` (docs/dynamics.md)."""

    v_max: float
    a_max: float
    c: float = 0.9
    admittance: float | None = None
    gain: float | None = None
    blend: bool = False
    braking: bool = False
    qd_max: np.ndarray | None = None
    qdd_max: np.ndarray | None = None
    force_filter_hz: float | None = None
    w_max: float | None = None
    dw_max: float | None = None

    def validate(self) -> None:
        for name in ("v_max", "a_max"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a finite number > 0, got {value}", field=name)
        check_c(self.c)
        if (self.admittance is None) == (self.gain is None):
            raise InputError("give exactly one of admittance (m/(N s)) or gain (1/(N s))", field="admittance")
        k = self.admittance if self.gain is None else self.gain
        if not (np.isfinite(k) and k > 0):
            raise InputError(f"regulator admittance/gain must be > 0, got {k}", field="admittance")
        if self.force_filter_hz is not None and not (np.isfinite(self.force_filter_hz) and self.force_filter_hz > 0):
            raise InputError(f"force_filter_hz must be > 0, got {self.force_filter_hz}", field="force_filter_hz")
        if (self.w_max is None) != (self.dw_max is None):
            raise InputError("give both orientation-rate limits w_max and dw_max, or neither", field="w_max")
        if self.w_max is not None and not (self.w_max > 0 and self.dw_max > 0):
            raise InputError(f"w_max and dw_max must be > 0, got {self.w_max}, {self.dw_max}", field="w_max")
        if (self.qd_max is None) != (self.qdd_max is None):
            raise InputError("give both joint velocity and acceleration limits, or neither", field="qd_max")


@dataclass
class MotionInstruction:
    """A validated MOVEJF / MOVELF. kind 'joint' or 'linear'; force f_des N; frame_id the tool;
    q_start the configuration the motion starts from (the end of the previous one)."""

    kind: str
    path: object
    force: float
    params: MotionParams
    frame_id: int
    q_start: np.ndarray = field(repr=False)


def _check_force(force: float) -> float:
    if not np.isfinite(force):
        raise InputError(f"force setpoint must be finite, got {force}", field="force")
    if force < 0:
        log.warning("negative tangential force setpoint %.3g N: the tool will pull along the path", force)
    return float(force)


def movejf(model: pin.Model, frame_id: int, q_start: np.ndarray, q_target: np.ndarray,
           params: MotionParams, force: float) -> MotionInstruction:
    """Joint-interpolated motion from q_start to q_target (nq,) with tangential force `force` N."""
    params.validate()
    f = _check_force(force)
    q_target = np.asarray(q_target, float)
    if q_target.shape != (model.nq,) or not np.all(np.isfinite(q_target)):
        raise InputError(f"target must be {model.nq} finite joint values", field="position")
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    if np.any(q_target < lo - 1e-12) or np.any(q_target > hi + 1e-12):
        raise InputError("target outside the joint limits", field="position")
    path = JointPath(model, frame_id, q_start, q_target)
    for s in np.linspace(0, 1, 17):          # a joint move whose TCP stays still has no tangent
        if np.linalg.norm(path.derivatives(s)[1]) < 1e-9:
            raise InputError(f"degenerate joint path: the tool does not translate at s = {s:.3f}",
                             field="position")
    return MotionInstruction("joint", path, f, params, frame_id, np.array(q_start, float))


def movelf(model: pin.Model, frame_id: int, q_start: np.ndarray, target: pin.SE3, params: MotionParams,
           force: float, ik_tolerance: float = 1e-10, check_points: int = 21) -> MotionInstruction:
    """Straight-line motion of the tool to `target` (world pose) with tangential force `force` N."""
    params.validate()
    f = _check_force(force)
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q_start, float))
    start = data.oMf[frame_id].copy()
    path = LinearPath(start, target) if np.linalg.norm(target.translation - start.translation) > 1e-9 \
        else None
    if path is None:
        raise InputError("degenerate straight line: target position equals the start position", field="position")
    check_reachable(model, frame_id, path, q_start, ik_tolerance, check_points)
    return MotionInstruction("linear", path, f, params, frame_id, np.array(q_start, float))


def movecf(model: pin.Model, frame_id: int, q_start: np.ndarray, path: CartesianPath, params: MotionParams,
           force: float, ik_tolerance: float = 1e-10, check_points: int = 41) -> MotionInstruction:
    """Motion of the tool along any Cartesian path (arc, spline, blended polyline) that starts at
    the tool's current position, with tangential force `force` N (spec §4-A: any differentiable f)."""
    params.validate()
    f = _check_force(force)
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q_start, float))
    gap = np.linalg.norm(path.derivatives(0.0)[0] - data.oMf[frame_id].translation)
    if gap > 1e-6:
        raise InputError(f"the path starts {gap:.3g} m away from the tool", field="path")
    path.check_regular()
    check_reachable(model, frame_id, path, q_start, ik_tolerance, check_points)
    return MotionInstruction("cartesian", path, f, params, frame_id, np.array(q_start, float))


def check_reachable(model: pin.Model, frame_id: int, path, q_start: np.ndarray, ik_tolerance: float,
                    check_points: int) -> None:
    """Follow the path by warm-started IK at check_points values of s; refuse it (InputError) where
    IK fails or a joint leaves its position limits (joint_projection.check_position_limits)."""
    data = model.createData()
    q = np.array(q_start, float)
    for s in np.linspace(0, 1, check_points):
        try:
            q = solve_ik(model, frame_id, path.pose(s), q, data=data, **tick_ik_options(ik_tolerance))
        except IKFailure as exc:
            raise InputError(f"the path is not reachable at s = {s:.3f}: {exc.reason}", field="position") from exc
        check_position_limits(model, q, s)


#: rad per IK iteration: a path tick never jumps to another branch
TICK_MAX_STEP = 0.5


def tick_ik_options(tolerance: float) -> dict:
    """solve_ik's settings for a motion tick: |log6(target^-1 M)| <= tolerance (2-norm, m and rad), steps capped
    at TICK_MAX_STEP, a tiny damping instead of the singularity check (docs/dynamics.md)."""
    # solve_ik stops on the largest of the 6 components; below tolerance / sqrt(6) the 2-norm is within it
    return {"tol": tolerance / np.sqrt(6.0), "max_iterations": 50, "singular_rcond": None, "damping": 1e-12,
            "max_step": TICK_MAX_STEP}
