"""Planning with contact measurement types: candidates are moved onto the nominal contact, unreachable ones
are left out, and the selection beats random choices."""
import numpy as np
import pinocchio as pin

from robocal import load_example
from robocal.design.selection import DesignMatrix, select_poses
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.residuals import PlaneResidual, SphereResidual
from robocal.design.simulate import random_configurations


def contact_candidates(n_plane=60, n_sphere=60, n_far=5):
    robot = load_example("ur5")
    robot.add_frame("probe", "tool0", pin.SE3(np.eye(3), np.array([0.01, 0.02, 0.12])))
    joints = robot.joint_names
    values = random_configurations(robot, joints, n_plane + n_sphere + n_far, np.random.default_rng(3), span=0.6)
    s = np.arange(len(values))
    blocks = [PlaneResidual("table", "probe", s[:n_plane], normal=(0, 0, 1), offset=0.05, tip_radius=0.003),
              SphereResidual("ball", "probe", s[n_plane:n_plane + n_sphere], centre=(0.4, 0.2, 0.3), radius=0.0125,
                             tip_radius=0.003),
              # a ball 5 m away: no candidate can touch it
              SphereResidual("far", "probe", s[n_plane + n_sphere:], centre=(5.0, 0.0, 0.0), radius=0.0125)]
    return Problem(robot, robot_parameters(robot, joints, "offsets"), joints, values, blocks), n_plane + n_sphere


def test_contact_candidates_are_placed_on_their_contact_and_unreachable_ones_dropped():
    problem, n_reachable = contact_candidates()
    design = DesignMatrix.from_problem(problem)
    assert design.n_candidates == n_reachable                  # the 5 candidates for the far ball are gone
    ev = problem.evaluate(jacobian=False)
    reachable_rows = ev.raw[:n_reachable]                        # one row per plane / sphere contact
    assert np.abs(reachable_rows).max() < 1e-12                  # every kept candidate touches its contact


def test_d_optimal_contact_plan_beats_random_sets():
    problem, n = contact_candidates()
    design = DesignMatrix.from_problem(problem)
    sel = select_poses(design, 15, "D")
    assert sel.identifiability.ok
    rng = np.random.default_rng(5)
    best_random = max(design.criteria(rng.choice(n, 15, replace=False))["D"] for _ in range(50))
    assert sel.values["D"] > best_random


def test_robocal_plan_with_a_plane_block_writes_poses_on_the_plane(tmp_path):
    import yaml
    from robocal.model.kinematics import ModelState
    from robocal.model.parameters import ParameterSet
    from robocal.workflows.plan import plan_from_config, write_plan
    cfg = {"robot": {"example": "ur5", "frames": [{"name": "probe", "parent": "tool0", "xyz": [0.01, 0.02, 0.12]}]},
           "data": {"csv": "touches.csv"},
           "parameters": {"preset": "offsets"},
           "measurements": [{"type": "plane", "name": "table", "frame": "probe", "normal": [0, 0, 1],
                             "offset": 0.05, "tip_radius": 0.003, "sigma": 1e-5}],
           "plan": {"N": 12, "seed": 2, "candidates": {"count": 80}, "validation": 20}}
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(cfg))
    plan = plan_from_config(path)
    write_plan(plan, tmp_path / "out")
    robot = load_example("ur5")
    robot.add_frame("probe", "tool0", pin.SE3(np.eye(3), np.array([0.01, 0.02, 0.12])))
    ms = ModelState(robot, ParameterSet(), robot.joint_names)
    heights = [ms.sample(q).pose("probe").translation[2] for q in plan.poses]
    assert len(heights) == 12 and np.allclose(heights, 0.053, atol=1e-9)   # tip centre 3 mm above the plane


def test_robocal_plan_refuses_a_contact_block_beside_others(tmp_path):
    import pytest
    import yaml
    from robocal.errors import InputError
    from robocal.workflows.plan import plan_from_config
    cfg = {"robot": {"example": "ur5"}, "data": {"csv": "x.csv"}, "parameters": {"preset": "offsets"},
           "measurements": [{"type": "plane", "frame": "tool0", "normal": [0, 0, 1], "offset": 0.05},
                            {"type": "sphere", "frame": "tool0", "centre": [0.4, 0, 0.3], "radius": 0.01}],
           "plan": {"N": 5, "candidates": {"count": 30}}}
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(cfg))
    with pytest.raises(InputError, match="measurements\\[0\\].type.*only"):
        plan_from_config(path)
