"""Force regulation under stiction: model error -> force band, speed ripple, free-space bias, feed speed.

The plant of robocal.dynamics.force_scenario (UR5, PID servos, stick-slip joints with breakaway 1.25 x
Coulomb, 5 mA current noise, one tick of sensor delay, a wall 30 mm ahead, 20 N setpoint), with the
estimator's friction and torque constants off by the factors in the first column, or identified by
identify_dynamics from a simulated excitation of the same plant. Each row is run with the former design
(raw current-based estimate, 10 Hz filter) and the contact observer, both at the admittance from
admittance_for_margins with the delay in the loop model, on noise seeds 1-3, against walls of 2e4 and
1e5 N/m; a band is the union over the seeds. The last second of a 6 s run is the steady window.
First the diagnostics behind the design (docs/dynamics.md, "Under stiction"). Prints the markdown tables.
Run:  OMP_NUM_THREADS=1 python benchmarks/force_regulation_realism.py   (about 10 minutes)
"""
import time

import numpy as np
import pinocchio as pin

import robocal
from robocal.dynamics import ActuatorModel, ForceFilter, admittance_for_margins, servo_gains, tangent_loop
from robocal.dynamics.contact_line import ContactLine
from robocal.dynamics.force_scenario import (Plant, deburr, excitation_segment, identify_friction, scaled_actuator,
                                             scaled_friction)
from robocal.dynamics.friction import FrictionModel
from robocal.dynamics.identification import identify_dynamics
from robocal.dynamics.stick_slip import StickSlipFriction

Q0 = np.array([0.3, -1.2, 1.5, -1.9, -1.5, 0.2])
F_DES, TOL, SEEDS = 20.0, 0.05, (1, 2, 3)
robot = robocal.load_example("ur5")
m, fid = robot.model, robot.frame_id("tool0")
coulomb = np.array([3, 3, 2, 1, 1, 0.8])
plant = Plant(m, fid, Q0, ActuatorModel([0.12, 0.12, 0.11, 0.09, 0.09, 0.08], gear_ratio=[101] * 6),
              StickSlipFriction(coulomb, 1.25 * coulomb, [5, 5, 3, 1, 1, 1], 0.01), servo_gains(m, Q0))
along = np.array([1.0, 0, 0])
loop = tangent_loop(m, Q0, fid, plant.gains, along, plant.friction, plant.period, delay=plant.delay)
admittance = admittance_for_margins(loop, 1e5, ForceFilter(10.0, plant.period), min_stiffness=1e3)
t0 = time.time()

# ---- diagnostics ---------------------------------------------------------------------------------
ident = identify_friction(plant)
dt = plant.period / 4                                                     # the simulator's substep
print(f"identification: {ident.message}; Coulomb {np.round(ident.friction.coulomb, 2)} (true {coulomb})")
print(f"viscous identified {np.round(ident.friction.viscous, 2)}, minus true [5 5 3 1 1 1]: "
      f"{np.round(ident.friction.viscous - plant.friction.viscous, 2)}; -kp dt (current sample one substep late): "
      f"{np.round(-plant.gains[0] * dt, 2)}")
segment = excitation_segment(plant)
n = m.nv
print("with a Stribeck term, per Stribeck velocity: residual rms per joint N m, identified viscous")
base = identify_dynamics(m, [segment], plant.actuator, FrictionModel(np.zeros(n), smoothing=1e-3),
                         current_noise=plant.current_noise)
print(f"  none  : {np.round(base.residual_rms, 3)}  {np.round(base.friction.viscous, 2)}")
for vs in (0.003, 0.01, 0.03):
    r = identify_dynamics(m, [segment], plant.actuator, FrictionModel(np.zeros(n), stribeck_velocity=vs, smoothing=1e-3),
                          terms=("coulomb", "viscous", "offset", "stribeck"), current_noise=plant.current_noise)
    print(f"  {vs:<6g}: {np.round(r.residual_rms, 3)}  {np.round(r.friction.viscous, 2)}")
data = m.createData()
J = pin.computeFrameJacobian(m, data, Q0, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3, 1:4]
axis = np.linalg.svd(J.T)[2][-1]
print(f"joints 2-4: rank {np.linalg.matrix_rank(J, 1e-9)} rows; a 3-component force fitted to them reads "
      f"F_u x {1 - (along @ axis) ** 2:.3f}")
k_s = loop.servo_stiffness
print(f"servo stiffness along the path K_s = {k_s:.0f} N/m; press speed / cruise speed 1/(1 + k_e/K_s) = "
      + ", ".join(f"{1 / (1 + k / k_s):.2f} at {k:.0e}" for k in (5e3, 2e4, 1e5)))
print(f"admittance {admittance:.3e} m/(N s) (delay {plant.delay} tick in the loop model): free-space feed "
      f"{admittance * F_DES * 1e3:.1f} mm/s; line loop T a k = " + ", ".join(
          f"{plant.period * admittance * k:.3f} at {k:.0e}" for k in (2e4, 1e5)))
f_cross = admittance * 1e5 / (2 * np.pi)
phase = np.degrees(np.angle(ForceFilter(10.0, plant.period).response(np.exp(2j * np.pi * f_cross * plant.period))))
print(f"with the 10 Hz filter on the line: crossover {f_cross:.1f} Hz at 1e5 N/m, filter phase {phase:.0f} deg there")


def largest_feed(k_e, sigma=0.2, precision=0.01, detect=0.1):
    """Largest feed m/s at which a press (samples every k_e v' T N from detect f_des) reaches the line
    precision at f_des before a sample reaches f_des; v' = v/(1 + k_e/K_s)."""
    for v in np.arange(0.5, 100.0, 0.25) * 1e-3:
        step, line = k_e * v / (1 + k_e / k_s) * plant.period, ContactLine()
        force, ok = detect * F_DES, False
        while force < F_DES:
            line.add(force / k_e, force)
            if line.samples >= 2 and line.prediction_std(F_DES / k_e, sigma) <= precision * F_DES:
                ok = True
                break
            force += step
        if not ok:
            return v - 0.25e-3
    return np.inf


feeds = {k: largest_feed(k) for k in (5e3, 2e4, 1e5)}
print("largest feed for the press (0.2 N sample noise, 1 % precision): " + ", ".join(
    (f"{v * 1e3:.1f} mm/s" if np.isfinite(v) else "above 100 mm/s") + f" at {k:.0e} N/m" for k, v in feeds.items()))
print(f"({time.time() - t0:.0f} s)\n")

# ---- the table -----------------------------------------------------------------------------------
cases = [("exact friction and K_t", 1.0, 1.0), ("friction x 0.5", 0.5, 1.0), ("friction x 1.5", 1.5, 1.0),
         ("K_t x 0.95", 1.0, 0.95), ("K_t x 1.05", 1.0, 1.05), ("friction x 0.5, K_t x 0.95", 0.5, 0.95),
         ("friction x 0.5, K_t x 1.05", 0.5, 1.05), ("friction x 1.5, K_t x 0.95", 1.5, 0.95),
         ("friction x 1.5, K_t x 1.05", 1.5, 1.05), ("identified (Coulomb, viscous, offset; nominal K_t)", None, 1.0),
         ("no friction model", 0.0, 1.0)]


def row(name, design, runs):
    lo, hi = min(r.true_band[0] for r in runs), max(r.true_band[1] for r in runs)
    ripple = max(r.speed_ripple for r in runs)
    ok = abs(lo - F_DES) <= TOL * F_DES and abs(hi - F_DES) <= TOL * F_DES and ripple < 0.1
    cells = [name, design, f"{lo:.2f}..{hi:.2f} ({100 * (lo / F_DES - 1):+.1f}..{100 * (hi / F_DES - 1):+.1f} %)",
             "yes" if ok else "no", f"{ripple:.2f}", f"{max(abs(r.free_bias) for r in runs):.2f}",
             f"{np.mean([r.feed_speed for r in runs]):.1f}", f"{max(r.peak for r in runs):.1f}"]
    obs = [r.observer for r in runs if r.observer is not None]
    if obs:
        cells += [" / ".join(f"{o.scale.scale:.3f}" for o in obs), " / ".join(str(o.line.samples) for o in obs),
                  f"{min(r.command_force for r in runs) - F_DES:+.2f}..{max(r.command_force for r in runs) - F_DES:+.2f}",
                  f"{min(r.true_band[1] - r.command_force for r in runs):+.2f}..{max(r.true_band[1] - r.command_force for r in runs):+.2f}"]
    else:
        cells += ["", "", "", ""]
    print("| " + " | ".join(cells) + " |", flush=True)


for stiffness in (2e4, 1e5):
    print(f"\nwall {stiffness:.0e} N/m, seeds {SEEDS}\n")
    print("| estimator's model | design | true force [N] (band over seeds, % of 20 N) | within +-5 % "
          "| speed ripple p-p [mm/s] | max free-space bias [N] | free-space feed [mm/s] | peak force [N] "
          "| K_t scale per seed | line samples per seed | wall force at the command - 20 [N] | true - wall force at the command [N] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, fr, kt in cases:
        friction = ident.friction if fr is None else scaled_friction(plant.friction, fr)
        model = ident.model(m) if fr is None else None
        for design, observer in (("former", False), ("observer", True)):
            runs = [deburr(plant, friction, scaled_actuator(plant.actuator, kt), admittance=admittance, model=model,
                           observer=observer, stiffness=stiffness, seed=s) for s in SEEDS]
            row(name, design, runs)

print("\nwall 1e5 N/m at a fifth of the feed (admittance / 5), observer, 14 s runs\n")
for name, fr, kt in (cases[0], cases[9]):
    friction = ident.friction if fr is None else scaled_friction(plant.friction, fr)
    runs = [deburr(plant, friction, scaled_actuator(plant.actuator, kt), admittance=admittance / 5, stiffness=1e5,
                   model=ident.model(m) if fr is None else None, ticks=3500, seed=s) for s in SEEDS]
    row(name, "observer", runs)
print(f"\n({time.time() - t0:.0f} s)")
