"""One control tick of force-regulated path following with the force estimated from motor currents.

The path generator takes the wrench estimated at the previous tick, the servo runs the setpoint, and the
estimator turns the measured positions (differentiated one tick late) and the previous tick's currents
into the next wrench: the loop docs/dynamics.md analyses. Simulations, tests and the example run it.
"""
from __future__ import annotations

import numpy as np

from robocal.dynamics.differentiation import TickDifferentiator
from robocal.dynamics.external_force import ExternalForceEstimator
from robocal.dynamics.generator import PathGenerator


class CurrentForceLoop:
    """generator -> servo (anything with `step(q_des)` returning q_mes and current) -> estimator -> generator."""

    def __init__(self, generator: PathGenerator, servo, estimator: ExternalForceEstimator,
                 differentiator: TickDifferentiator):
        self.generator, self.servo, self.estimator, self.differentiator = generator, servo, estimator, differentiator
        self.wrench = np.zeros(6)          # estimated at the last tick, fed to the next
        self.last_current = None

    def tick(self):
        """(setpoint, measurement) of one tick."""
        setpoint = self.generator.tick(self.wrench)
        measured = self.servo.step(setpoint.q_des)
        state = self.differentiator.push(measured.q_mes)
        if state is not None and self.last_current is not None:
            self.wrench = self.estimator.tick(*state, self.last_current)[0]
        self.last_current = measured.current
        return setpoint, measured
