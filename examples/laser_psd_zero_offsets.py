"""Zero offsets of an ABB IRB1600 from a laser on the flange and a PSD at an unknown place (seed 001).

Simulates the acquisition (the controller knows only the nominal model; the true robot has zero offsets;
the spot is servoed onto the PSD centre; joints are read three times per pose with noise), calibrates,
and prints offsets before/after with the predicted and achieved accuracy (degrees). Run:
    OMP_NUM_THREADS=1 python examples/laser_psd_zero_offsets.py [patent|three_fans]
"""
import logging
import sys
from pathlib import Path

import numpy as np

from robocal.systems.laser_psd.calibration import LaserMount, calibrate_laser, offset_report, reading_noise_covariance, zero_offset_problem
from robocal.systems.laser_psd.plans import PlannedPose, multi_fan, patent_fan, plan_configurations
from robocal.systems.laser_psd.simulation import PSD, SimRobot, acquire
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters
from robocal.model.robot import load_urdf

ROOT = Path(__file__).resolve().parents[1]
design = sys.argv[1] if len(sys.argv) > 1 else "three_fans"
robot = load_urdf(ROOT / "urdf" / "abb_irb1600.urdf")
joints = robot.joint_names
mount = LaserMount([0.0, 0.04, 0.08], [0.0, 0.0, 1.0])            # laser 40 mm off the flange axis
psd_centre = np.array([0.95, 0.10, 0.30])                          # unknown to the calibration
direction = np.array([0.3, 0.0, -1.0]) / np.linalg.norm([0.3, 0.0, -1.0])
roll = np.radians(-90.0)
sigma_q = np.radians(0.0005)                                       # per averaged reading

truth = robot_parameters(robot, joints, "offsets")
delta_true = np.radians([0.3, -0.2, 0.25, -0.4, 0.3, 0.2])
for j, d in zip(joints, delta_true):
    truth[f"{j}.offset"].value = d
plan = patent_fan() if design == "patent" else multi_fan()

# the operator's first jog: the true beam somewhere on the PSD (here 2 mm off its centre)
ms_true = ModelState(robot, truth, joints)
q_start = plan_configurations(robot, ms_true, joints, mount, [PlannedPose(np.eye(3), 0.35, 0, 0.0)],
                              psd_centre + [0.0, 0.002, 0.0], direction, roll)[0]
sim = SimRobot(robot, truth, joints, mount, reading_noise=sigma_q * np.sqrt(3), rng=np.random.default_rng(1))
acq = acquire(robot, robot_parameters(robot, joints, "offsets"), joints, sim, PSD(psd_centre, -direction), plan,
              direction, q_start, roll, n_reads=3)
print(f"design {design}: {len(plan)} poses, servo iterations per pose {[r.iterations for r in acq.servo]}, "
      f"true beam within {acq.miss.max() * 1e6:.2f} um of the PSD centre")

problem = zero_offset_problem(robot, joints, acq.readings, mount, sigma=5e-6)
cal = calibrate_laser(problem, mount)
cov = reading_noise_covariance(problem, sigma_q)
names = problem.params.free_names
print(f"\n{'joint':<9}{'true':>10}{'before':>10}{'after':>11}{'error':>11}{'predicted sd':>14}   (deg)")
for rep, d in zip(offset_report(cal.result, joints), delta_true):
    n = f"{rep.joint}.offset"
    if rep.identified:
        sd = np.degrees(np.sqrt(cov[names.index(n), names.index(n)]))
        print(f"{rep.joint:<9}{np.degrees(d):>10.4f}{0.0:>10.4f}{rep.value_deg:>11.5f}"
              f"{rep.value_deg - np.degrees(d):>+11.5f}{sd:>14.5f}")
    else:
        print(f"{rep.joint:<9}{np.degrees(d):>10.4f}{0.0:>10.4f}{'not identifiable':>36}")
c = [problem.params[f"psd.target.{k}"].value * 1e3 for k in "xyz"]
print(f"\nPSD centre found at ({c[0]:.2f}, {c[1]:.2f}, {c[2]:.2f}) mm (true: {psd_centre * 1e3} mm, turned "
      f"about base z by joint 1's unknown offset)")
print(f"line-to-point RMS after the fit: {cal.result.after[0].rms['mm'] * 1e3:.3f} um")
print("\n" + "\n".join(cal.statements + cal.result.identifiability_statements()))
logging.shutdown()
