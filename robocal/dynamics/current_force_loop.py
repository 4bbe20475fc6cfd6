"""One control tick of force-regulated path following with the force estimated from motor currents.

The path generator takes the wrench estimated at the previous tick, the servo runs the setpoint, and the
estimator turns the measured positions (differentiated one tick late) and the previous tick's currents
into the next wrench: the loop docs/dynamics.md analyses. Simulations, tests and the example run it.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.dynamics.differentiation import TickDifferentiator
from robocal.dynamics.external_force import ExternalForceEstimator
from robocal.dynamics.contact_observer import ContactForceObserver
from robocal.dynamics.generator import PathGenerator


class CurrentForceLoop:
    """generator -> servo (anything with `step(q_des)` returning q_mes and current) -> estimator -> generator."""

    def __init__(self, generator: PathGenerator, servo, estimator: ExternalForceEstimator,
                 differentiator: TickDifferentiator, observer: ContactForceObserver | None = None):
        self.generator, self.servo, self.estimator, self.differentiator = generator, servo, estimator, differentiator
        self.observer = observer           # None: the raw estimate, as in the patent
        self.wrench = np.zeros(6)          # estimated at the last tick, fed to the next
        self.last_current = None
        self.raw_force = 0.0               # tangential component of the last raw estimate

    def tick(self):
        """(setpoint, measurement) of one tick."""
        setpoint = self.generator.tick(self.wrench)
        measured = self.servo.step(setpoint.q_des)
        state = self.differentiator.push(measured.q_mes)
        if state is not None and self.last_current is not None:
            self.wrench = self.estimator.tick(*state, self.last_current)[0]
            if self.observer is not None:
                self.wrench = self._observed(self.wrench, state[0], state[1])
        self.last_current = measured.current
        return setpoint, measured

    def _observed(self, wrench: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The wrench with its component along the path tangent replaced by the observer's value."""
        gen, est = self.generator, self.estimator
        m, d = est.model, est.data
        u = gen.instruction.path.derivatives(gen.s)[1]
        u = u / np.linalg.norm(u)
        J = pin.computeFrameJacobian(m, d, q, est.frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).reshape(6, -1)
        pin.framesForwardKinematics(m, d, q)
        x_u = float(d.oMf[est.frame_id].translation @ u)
        torque = J.T @ wrench                     # the external joint torques the estimate came from
        pin.framesForwardKinematics(m, d, gen.q_des)
        x_cmd = float(d.oMf[est.frame_id].translation @ u)   # the setpoint the servos are driving to
        self.raw_force = float(wrench[:3] @ u)
        gravity = pin.computeGeneralizedGravity(m, d, q)          # the model's, for the torque-constant scale
        force = self.observer.update(torque, J[:3], u, x_u, v, x_cmd, gravity)
        return wrench + np.r_[(force - self.raw_force) * u, 0.0, 0.0, 0.0]
