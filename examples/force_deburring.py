"""Force-regulated deburring along a line against a wall (seed 004), on a simulated UR5.

The tool moves along +x (MOVELF) with a 20 N tangential-force setpoint. A wall across the path
(stiffness 2e4 N/m) stops it; the force is estimated from synthesised motor currents (noisy) minus
RNEA and friction. Prints the approach, the contact force and the final progress along the path.
Run:  OMP_NUM_THREADS=1 python examples/force_deburring.py
"""
import numpy as np
import pinocchio as pin

import robocal
from robocal.dynamics import (ActuatorModel, Environment, ExternalForceEstimator, FrictionModel, MotionParams,
                              PathGenerator, RobotSimulator, TickDifferentiator, Wall, movelf, servo_gains)

robot = robocal.load_example("ur5")
model, tcp = robot.model, robot.frame_id("tool0")
q0 = np.array([0.3, -1.2, 1.5, -1.9, -1.5, 0.2])
actuator = ActuatorModel([0.12, 0.12, 0.11, 0.09, 0.09, 0.08], gear_ratio=[101] * 6)
friction = FrictionModel([3, 3, 2, 1, 1, 0.8], viscous=[5, 5, 3, 1, 1, 1], smoothing=0.01)

data = model.createData()
pin.framesForwardKinematics(model, data, q0)
start = data.oMf[tcp].copy()
along = np.array([1.0, 0.0, 0.0])
wall = Wall(start.translation + 0.03 * along, along, stiffness=2e4)
sim = RobotSimulator(model, tcp, q0, actuator, friction, Environment(wall), servo_gains(model, q0),
                     current_noise=0.005, seed=1)

instruction = movelf(model, tcp, q0, pin.SE3(start.rotation, start.translation + 0.2 * along),
                     MotionParams(v_max=0.25, a_max=1.0, admittance=0.002), force=20.0)
generator = PathGenerator(model, instruction)
estimator = ExternalForceEstimator(model, tcp, actuator, friction)
differentiator = TickDifferentiator(0.004, "central")       # one tick late, second-order accurate

wrench, last_current = np.zeros(6), None
print(f"{'t [s]':>6s} {'s':>7s} {'speed [mm/s]':>13s} {'F_T est [N]':>12s} {'F_T true [N]':>13s}")
for k in range(1000):
    setpoint = generator.tick(wrench)
    measured = sim.step(setpoint.q_des)
    state = differentiator.push(measured.q_mes)
    if state is not None and last_current is not None:
        wrench, _ = estimator.tick(*state, last_current)
    last_current = measured.current
    if k % 100 == 99:
        print(f"{(k + 1) * 0.004:6.2f} {setpoint.s:7.4f} {setpoint.sd * 200:13.2f} {wrench[:3] @ along:12.2f} "
              f"{measured.true_wrench[:3] @ along:13.2f}")
