"""A closed-loop machine's result builds a scene whose every sample has its loops closed."""
import json
from functools import lru_cache

import numpy as np

from robocal.estimation.calibrate import calibrate
from robocal.estimation.problem import Problem
from robocal.residuals import PoseResidual
from robocal.viz.scene import scene_bytes
from robocal.design.simulate import perturb, simulate_measurements
from robocal.viz.meshcat_check import SceneView
from test_loop_sensitivities import stewart_problem


@lru_cache(maxsize=1)
def stewart_case():
    """Stewart 6-6, 16 poses, tracker on the tool, calibrated: (problem after the fit, result, before)."""
    rng = np.random.default_rng(0)
    robot, ps, act, lengths = stewart_problem(rng, 16)   # 96 rows for the 90 requested parameters
    for p in ps:
        p.value = 0.0
    n = len(lengths)
    problem = Problem(robot, ps, act, lengths, [PoseResidual("tracker", "tool", np.arange(n),
                                                             np.tile([0, 0, 0, 0, 0, 0, 1.0], (n, 1)),
                                                             sigma=(1e-5, 1e-5))])
    simulate_measurements(problem, perturb(problem.params, rng, 1e-3, 1e-3), rng)
    before = problem.params.copy()
    return problem, calibrate(problem), before


def stewart_scene() -> dict:
    problem, result, before = stewart_case()
    return json.loads(scene_bytes(problem, result, before))


def test_stewart_result_scene_has_closed_loops_and_exports():
    problem, _, _ = stewart_case()
    robot = problem.robot
    scene = stewart_scene()
    n = len(problem.values)
    assert len(scene["values"]) == n
    # every closure's two anchors coincide in the recorded link poses (the loops are drawn closed)
    states = problem.states()
    for i in range(n):
        s = states[i]
        for c in robot.loops.closures:
            assert np.linalg.norm(s.pose(c.frame1).translation - s.pose(c.frame2).translation) < 1e-9
    closures = scene["robot"]["closures"]
    assert len(closures) == 6 and all(c["links"][1] == "platform" for c in closures)
    assert all(f in scene["frames"] for c in closures for f in c["frames"])   # anchors recorded per sample
    html = SceneView(scene, meshes=False).static_html()
    assert "<html" in html.lower() and len(html) > 100_000
