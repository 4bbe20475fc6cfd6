"""Force regulation under stiction: model error -> force band, speed ripple, free-space bias, feed speed.

The plant of robocal.dynamics.force_scenario (UR5, PID servos, stick-slip joints with breakaway 1.25 x
Coulomb, 5 mA current noise, one tick of sensor delay, a 2e4 N/m wall 30 mm ahead, 20 N setpoint),
with the estimator's friction and torque constants off by the factors in the first column, or
identified by identify_dynamics from a simulated excitation of the same plant. Each row is run with
the former design (raw current-based estimate, admittance 7.58e-4, 10 Hz filter) and the new one
(contact observer, admittance from admittance_for_margins with the delay in the loop model).
The last second of a 6 s run is the steady window. Prints the markdown table of docs/dynamics.md.
Run:  OMP_NUM_THREADS=1 python benchmarks/force_regulation_realism.py   (about 3 minutes)
"""
import time

import numpy as np

import robocal
from robocal.dynamics import ActuatorModel, ForceFilter, admittance_for_margins, servo_gains, tangent_loop
from robocal.dynamics.force_scenario import Plant, deburr, identify_friction, scaled_actuator, scaled_friction
from robocal.dynamics.stick_slip import StickSlipFriction

Q0 = np.array([0.3, -1.2, 1.5, -1.9, -1.5, 0.2])
F_DES, TOL = 20.0, 0.05
robot = robocal.load_example("ur5")
m, fid = robot.model, robot.frame_id("tool0")
coulomb = np.array([3, 3, 2, 1, 1, 0.8])
plant = Plant(m, fid, Q0, ActuatorModel([0.12, 0.12, 0.11, 0.09, 0.09, 0.08], gear_ratio=[101] * 6),
              StickSlipFriction(coulomb, 1.25 * coulomb, [5, 5, 3, 1, 1, 1], 0.01), servo_gains(m, Q0))
loop = tangent_loop(m, Q0, fid, plant.gains, np.array([1.0, 0, 0]), plant.friction, plant.period, delay=plant.delay)
new_admittance = admittance_for_margins(loop, 1e5, ForceFilter(10.0, plant.period), min_stiffness=1e3)
t0 = time.time()
ident = identify_friction(plant)
print(f"identification: {ident.message}; Coulomb {np.round(ident.friction.coulomb, 2)} "
      f"(true {coulomb}), viscous {np.round(ident.friction.viscous, 2)} (true [5 5 3 1 1 1]) ({time.time() - t0:.0f} s)")
print(f"new design admittance {new_admittance:.3e} m/(N s) (delay {plant.delay} tick in the loop model)")

cases = [("exact friction and K_t", 1.0, 1.0), ("friction x 0.5", 0.5, 1.0), ("friction x 1.5", 1.5, 1.0),
         ("K_t x 0.95", 1.0, 0.95), ("K_t x 1.05", 1.0, 1.05), ("friction x 0.5, K_t x 1.05", 0.5, 1.05),
         ("friction x 1.5, K_t x 0.95", 1.5, 0.95), ("identified (Coulomb, viscous, offset; nominal K_t)", None, 1.0),
         ("no friction model", 0.0, 1.0)]
print("\n| estimator's model | design | true force [N] (band, % of 20 N) | within +-5 % | speed ripple p-p [mm/s] "
      "| free-space bias [N] | free-space feed [mm/s] |\n|---|---|---|---|---|---|---|")
for name, fr, kt in cases:
    friction = ident.friction if fr is None else scaled_friction(plant.friction, fr)
    model = ident.model(m) if fr is None else None
    for design, kwargs in (("former", dict(observer=False)), ("observer", dict(admittance=new_admittance))):
        r = deburr(plant, friction, scaled_actuator(plant.actuator, kt), model=model, **kwargs)
        lo, hi = r.true_band
        ok = abs(lo - F_DES) <= TOL * F_DES and abs(hi - F_DES) <= TOL * F_DES and r.speed_ripple < 0.1
        print(f"| {name} | {design} | {lo:.2f}..{hi:.2f} ({100 * (lo / F_DES - 1):+.1f}..{100 * (hi / F_DES - 1):+.1f} %) "
              f"| {'yes' if ok else 'no'} | {r.speed_ripple:.2f} | {r.free_bias:+.2f} | {r.feed_speed:.1f} |", flush=True)
print(f"\n({time.time() - t0:.0f} s)")
