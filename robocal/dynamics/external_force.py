"""External joint torques and wrench from motor currents (the patent's Fig. 6, blocks 701-800).

    C_ext = actuator.torque(I) - [rnea(q, v, a) + friction(v)]  =  J^T F
F is the wrench the robot exerts on its environment (spec §11.1, §13.13): pushing +x on a wall
gives F_x > 0. J is the frame Jacobian in LOCAL_WORLD_ALIGNED axes, so F is [force; moment about
the frame origin] in world axes. rnea includes model.armature (reflected rotor inertia) and any
payload attached with `payload.with_payload`; it ignores model.friction, hence the explicit term.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.dynamics.actuators import ActuatorModel
from robocal.dynamics.friction import FrictionModel
from robocal.dynamics.wrench import WrenchEstimate, WrenchMapper

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass
class ExternalForceEstimate(WrenchEstimate):
    """WrenchEstimate plus joint_torque (T, n) N m, the external joint torques C_ext."""

    joint_torque: np.ndarray | None = None


class ExternalForceEstimator:
    """Estimate C_ext and the wrench at `frame_id` over a log (batch) or per control tick.

    model     pin.Model including tool inertia (use payload.with_payload); not modified
    frame_id  frame where the wrench is expressed (the TCP)
    actuator  ActuatorModel (unit torque constants when None: currents are torques)
    friction  FrictionModel (none when None)
    mapper    WrenchMapper (defaults)
    """

    def __init__(self, model: pin.Model, frame_id: int, actuator: ActuatorModel | None = None,
                 friction: FrictionModel | None = None, mapper: WrenchMapper | None = None):
        nv = model.nv
        self.model, self.data = model, model.createData()
        if not 0 <= frame_id < model.nframes:
            raise InputError(f"frame id {frame_id} out of range (model has {model.nframes})", field="frame")
        self.frame_id = frame_id
        self.actuator = actuator or ActuatorModel.identity(nv)
        self.friction = friction or FrictionModel.none(nv)
        self.mapper = mapper or WrenchMapper()
        for name, part in (("actuator", self.actuator), ("friction", self.friction)):
            if part.n != nv:
                raise InputError(f"{name} has {part.n} joints, the model has nv = {nv}", field=name)

    # ---- batch ---------------------------------------------------------------------------
    def model_torques(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """C_d = rnea(q, v, a) + friction(v), (T, nv) N m."""
        q, v, a = self._check_log(q, v, a)
        m, d = self.model, self.data
        tau = np.empty((q.shape[0], m.nv))
        for k in range(q.shape[0]):
            tau[k] = pin.rnea(m, d, q[k], v[k], a[k])
        return tau + self.friction.torque(v)

    def joint_torques(self, q, v, a, current) -> np.ndarray:
        """C_ext (T, nv) N m from positions (T, nq) rad, velocities and accelerations (T, nv)
        and currents (T, nv) A."""
        return self.actuator.torque(current) - self.model_torques(q, v, a)

    def jacobians(self, q: np.ndarray) -> np.ndarray:
        """(T, 6, nv) frame Jacobians, LOCAL_WORLD_ALIGNED."""
        m, d, f = self.model, self.data, self.frame_id
        J = np.empty((q.shape[0], 6, m.nv))
        for k in range(q.shape[0]):
            J[k] = pin.computeFrameJacobian(m, d, q[k], f, _LWA).reshape(6, m.nv)
        return J

    def estimate(self, q, v, a, current) -> ExternalForceEstimate:
        """Wrench (T, 6) of the robot on its environment at the frame, with conditioning."""
        q, v, a = self._check_log(q, v, a)
        current = np.asarray(current, dtype=float)
        if current.shape != v.shape:
            raise InputError(f"currents must be {v.shape}, got {current.shape}", field="current")
        m, d, f = self.model, self.data, self.frame_id
        n = q.shape[0]
        tau = np.empty((n, m.nv))
        J = np.empty((n, 6, m.nv))
        for k in range(n):   # one pass: rnea then the Jacobian at the same q
            tau[k] = pin.rnea(m, d, q[k], v[k], a[k])
            J[k] = pin.computeFrameJacobian(m, d, q[k], f, _LWA).reshape(6, m.nv)
        c_ext = self.actuator.torque(current) - tau - self.friction.torque(v)
        w = self.mapper.map(J, c_ext)
        return ExternalForceEstimate(w.wrench, w.condition, w.damped, w.ill_conditioned, w.residual,
                                     joint_torque=c_ext)

    # ---- one control tick ----------------------------------------------------------------
    def tick(self, q, v, a, current) -> tuple[np.ndarray, float]:
        """One sample: wrench (6,) and cond(J). Same maths as `estimate`, without batch overhead."""
        m, d = self.model, self.data
        c_ext = (self.actuator.torque(current) - pin.rnea(m, d, q, v, a) - self.friction.torque(v))
        J = pin.computeFrameJacobian(m, d, q, self.frame_id, _LWA).reshape(6, m.nv)
        wrench, cond, _ = self.mapper.map_one(J, c_ext)
        return wrench, cond

    def _check_log(self, q, v, a):
        q, v, a = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, v, a))
        m = self.model
        if q.shape[1] != m.nq or v.shape != (q.shape[0], m.nv) or a.shape != v.shape:
            raise InputError(f"expected q (T, {m.nq}), v and a (T, {m.nv}); got {q.shape}, {v.shape}, "
                             f"{a.shape}", field="q")
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v)) and np.all(np.isfinite(a))):
            bad = int(np.argmax(~(np.isfinite(q).all(1) & np.isfinite(v).all(1) & np.isfinite(a).all(1))))
            raise InputError("non-finite joint state", row=bad, field="q")
        return q, v, a
