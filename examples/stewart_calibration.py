"""Calibrate the seed-000 Stewart platform from simulated data of each measuring mode, then of a mix.

Run:  OMP_NUM_THREADS=1 python examples/stewart_calibration.py
"""
from pathlib import Path

import numpy as np

import robocal
from robocal.systems.stewart import calibration as sc, modes as sm
from robocal.estimation.calibrate import calibrate
from robocal.estimation.problem import Problem

robot = robocal.load_urdf(Path(__file__).resolve().parents[1] / "urdf" / "stewart_6_6.urdf")
tool = sm.Tool(length=0.2, tip_radius=0.003)
rng = np.random.default_rng(0)
truth = sc.stewart_parameters()
for p in truth:
    p.value = rng.normal(0.0, 1e-3)               # the real machine: 1 mm off everywhere
true_geo = sc.geometry(robot, truth)


def acquire(tips):
    """Struts the true machine reads with its tool tip at `tips`, orientations varied +-15 deg."""
    abc, R = sc.random_orientations(len(tips), rng)
    return abc, sc.struts(true_geo, sc.tip_to_platform(tips, R, tool))


# mode 1: full poses; modes 2-5: plane, hole, ball, ball bar (3 locations, unknown offsets)
tips = sc.random_tips(12, rng)
abc, s1 = acquire(tips)
sets = {"mode 1 (poses)": (sm.pose_residuals("pose", robot, np.arange(12), np.column_stack([tips, abc]),
                                             [1, 1, 1, 1, 1, 1], tool, (1e-6, 1e-6)), s1)}
blocks, values = [], []
for k, c in enumerate([(0, 0, 0.22), (0.08, -0.05, 0.22), (-0.06, 0.07, 0.24)]):
    length = rng.uniform(0.09, 0.11, 30)
    _, s = acquire(sc.sphere_tips(c, length, 30, rng))
    blocks.append(sm.ball_bar_residual(f"dbb{k}", np.arange(30 * k, 30 * k + 30), length - 0.0123, c, tool))
    values.append(s)
sets["mode 5 (ball bar, T fixed)"] = (blocks, np.vstack(values))
for name, (residuals, s) in sets.items():
    params = sc.stewart_parameters(fix_platform_joints="T fixed" in name)
    for p in params:
        if not p.vary:
            p.value = truth[p.name].value              # T measured on a CMM
    result = calibrate(Problem(robot, params, sc.actuated(robot), s, residuals))
    err = max(abs(params[p.name].value - p.value) for p in truth)
    print(f"{name}: {result.status}, rank {result.selection.rank}, max parameter error {err:.2e} m")
    for line in sc.explain(result.solve.jac, robot, params, tool):
        print("   ", line)

# a mix: 12 poses + the ball bars, all 42 parameters free
mixed = sets["mode 1 (poses)"][0] + [sm.ball_bar_residual(b.name, b.samples + 12, b.measurements[:, 0],
                                                          [a.value for a in b.aux[:3]], tool) for b in blocks]
params = sc.stewart_parameters()
result = calibrate(Problem(robot, params, sc.actuated(robot), np.vstack([s1] + values), mixed))
print("mix:", result.summary().splitlines()[0])
vt = sc.random_tips(50, rng)
_, vR = sc.random_orientations(50, rng)
print(f"tool-tip error on 50 fresh poses: before {sc.tip_errors(true_geo, sc.geometry(robot, sc.stewart_parameters()), tool, vt, vR).max() * 1e3:.2f} mm, "
      f"after {sc.tip_errors(true_geo, sc.geometry(robot, params), tool, vt, vR).max() * 1e6:.3f} um")
