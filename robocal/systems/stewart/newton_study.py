"""The patent's Newton iteration from the spec's 1 mm set-up, on repeated draws: does it converge, and with which
safeguards (docs/stewart_calibration.md, "The patent's Newton iteration").

Set-up (docs/stewart_calibration.md, the spec's test 5): the 42 parameters drawn N(0, 1 mm), T fixed at its true value, the other
24 free from nominal; 6 noise-free full poses within +-15 deg; second derivatives by central differences
with step e = 1e-3 mm. `safeguarded=False` takes the literal full Newton step; True shifts the Hessian by
mu I until Cholesky succeeds and halves the step until F decreases (robocal.systems.stewart.newton).
Draw k uses its own seed (robocal.estimation.parallel_map.monte_carlo), so the counts are reproducible.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.errors import AssemblyError
from robocal.estimation.parallel_map import monte_carlo
from robocal.estimation.problem import Problem
from robocal.systems.stewart import calibration as sc
from robocal.systems.stewart import modes as sm
from robocal.systems.stewart.newton import patent_newton

STEP = 1e-6           # e = 1e-3 mm
POSES = 6


@dataclass
class NewtonOutcome:
    converged: bool
    iterations: int
    error: float          # largest |parameter - truth| at the end (m); inf when the loops broke
    failure: str          # "" or why it stopped
    unassemblable: int = 0    # line-search steps rejected because some pose's loops could not close


@dataclass
class NewtonTrial:
    robot: object
    tool: sm.Tool
    safeguarded: bool
    max_iterations: int = 40

    def __call__(self, rng: np.random.Generator) -> NewtonOutcome:
        truth = sc.stewart_parameters(fix_platform_joints=True)
        for p in truth:
            p.value = rng.normal(0.0, 1e-3)
        tips = sc.random_tips(POSES, rng)
        abc, R = sc.random_orientations(POSES, rng)
        s = sc.struts(sc.geometry(self.robot, truth), sc.tip_to_platform(tips, R, self.tool))
        params = sc.stewart_parameters(fix_platform_joints=True)
        for p in truth:
            if not p.vary:
                params[p.name].value = p.value
        rows = np.column_stack([tips, abc])
        problem = Problem(self.robot, params, sc.actuated(self.robot), s,
                          sm.pose_residuals("pose", self.robot, np.arange(POSES), rows, 1, self.tool, (1e-6, 1e-6)))
        try:
            res = patent_newton(problem, e=STEP, max_iterations=self.max_iterations, safeguarded=self.safeguarded)
        except AssemblyError:
            return NewtonOutcome(False, 0, float("inf"), "a step left the loops unclosable (AssemblyError)")
        error = max(abs(params[p.name].value - p.value) for p in truth)
        return NewtonOutcome(res.converged, res.iterations, float(error), "" if res.converged else "iteration cap",
                             res.unassemblable)


def newton_draws(robot, tool: sm.Tool, safeguarded: bool, draws: int, seed: int = 0,
                 scheduler: str | None = None, workers: int | None = None) -> list[NewtonOutcome]:
    """The outcome of the patent's Newton iteration on `draws` machines (draw k: k-th child of SeedSequence(seed))."""
    return monte_carlo(NewtonTrial(robot, tool, safeguarded), draws, seed, scheduler, workers)
