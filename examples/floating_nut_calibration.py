"""Calibrate the floating-nut hexapod through the generic layer, with and without nut-roll compensation.

Run:  OMP_NUM_THREADS=1 python examples/floating_nut_calibration.py [--write-docs | --check-docs]   (about 10 s)

A simulated machine differs from its URDF by 1 mm (1 sigma) in every Hooke centre and encoder zero and by
20 um in every screw lead. A 6D tracker (10 um, 10 urad) sees the platform at 40 poses. The compensated
model (the URDF's <screw_transmission> rows) recovers the machine; a classic 6-UPS model (the rows dropped)
absorbs the nut roll's additional length into the joint positions. --write-docs writes the table into
docs/floating_nut_hexapod.md, --check-docs checks that the page shows it.
"""
import sys
from pathlib import Path

import numpy as np

import robocal
from robocal import calibrate
from robocal.systems.floating_nut import floating_nut_parameters, uncompensated_robot
from robocal.model import ModelState
from robocal.systems.floating_nut import reference_fixture
from robocal.systems.floating_nut import FloatingNutKinematics
from robocal.estimation import Problem
from robocal.residuals import PoseResidual
from robocal.design import simulate_measurements
from robocal.io import page_differences, update_page

URDF = Path(__file__).resolve().parents[1] / "urdf" / "floating_nut_hexapod.urdf"
PAGE = Path(__file__).resolve().parents[1] / "docs" / "floating_nut_hexapod.md"
COMMAND = "OMP_NUM_THREADS=1 python examples/floating_nut_calibration.py"
SIGMA = (1e-5, 1e-5)
GEOMETRY = reference_fixture()
KIN = FloatingNutKinematics(GEOMETRY)
rng = np.random.default_rng(2026)


def readings_at(n):
    """Encoder readings (command lengths from home) that put the nominal machine at random poses."""
    poses = GEOMETRY.p0 + np.column_stack([rng.uniform(-0.15, 0.15, (n, 3)), np.deg2rad(rng.uniform(-15, 15, (n, 3)))])
    return poses, KIN.ik(poses) - KIN.ik(GEOMETRY.p0)


def tracker_problem(robot, params, readings):
    n = len(readings)
    return Problem(robot, params, robot.loops.actuated, readings,
                   [PoseResidual("platform_pose", "platform", np.arange(n), np.tile([0, 0, 0.8, 0, 0, 0, 1.0], (n, 1)),
                                 sigma=SIGMA)])


def centre_errors(params, truth):
    names = [f"leg{i}_hooke_base_1" for i in range(1, 7)] + [f"leg{i}_closure.link2" for i in range(1, 7)]
    return np.array([np.linalg.norm([params[f"{n}.{c}"].value - truth[f"{n}.{c}"].value for c in ("tx", "ty", "tz")])
                     for n in names])


robot = robocal.load_urdf(URDF)
truth = floating_nut_parameters(robot)
for p in truth:
    if p.vary:
        p.value += rng.normal(0, 2e-5 if p.name.endswith(".lead") else 1e-3)
poses, readings = readings_at(40)
print(f"nut-roll additional length over these poses: up to {np.abs(KIN.additional_lengths(poses)).max() * 1e3:.3f} mm")

compensated = tracker_problem(robot, floating_nut_parameters(robot), readings)
simulate_measurements(compensated, truth, rng)
plain = uncompensated_robot(robot)
uncompensated = tracker_problem(plain, floating_nut_parameters(plain, leads=False), readings)
uncompensated.residuals[0].set_measurements(compensated.residuals[0].measurements.copy())

new = readings_at(20)[1]
real = ModelState(robot, truth, robot.loops.actuated)
table = ["| model | parameters | tracker rms | Hooke centre error, max | error at 20 new poses, max |",
         "|---|---|---|---|---|"]
for label, problem, model_robot in (("compensated (screw rows)", compensated, robot),
                                    ("uncompensated (6-UPS)", uncompensated, plain)):
    result = calibrate(problem)
    rms = np.sqrt(np.mean(problem.evaluate().raw.reshape(-1, 6)[:, :3] ** 2))
    fitted = ModelState(model_robot, problem.params, robot.loops.actuated)
    miss = max(np.linalg.norm(fitted.sample(u).pose("platform").translation - real.sample(u).pose("platform").translation)
               for u in new)
    table.append(f"| {label} | {len(result.estimated)} | {rms * 1e6:.1f} um | "
                 f"{centre_errors(problem.params, truth).max() * 1e3:.3f} mm | {miss * 1e6:.1f} um |")
lead_err = max(abs(compensated.params[f"leg{i}_screw.lead"].value - truth[f"leg{i}_screw.lead"].value) for i in range(1, 7))
table += ["", f"Compensated fit: largest lead error {lead_err * 1e6:.2f} um "
          f"(stderr {max(compensated.params[f'leg{i}_screw.lead'].stderr for i in range(1, 7)) * 1e6:.2f} um)."]
blocks = {"calibration": "\n".join(table)}
if "--check-docs" in sys.argv:
    diffs = page_differences(PAGE, blocks)
    print("\n".join(diffs) or f"{PAGE.name} shows what this example prints")
    sys.exit(1 if diffs else 0)
print("\n" + blocks["calibration"])
if "--write-docs" in sys.argv:
    update_page(PAGE, blocks, COMMAND)
