"""Parameter and joint sensitivities through closed loops (implicit-function theorem) vs finite differences.

Every parameter kind on a Stewart platform: actuated-joint offsets (strut zero offsets o), placements of
passive joints (base joints N), loop-anchor frames (platform joints T), a tool frame and the base frame,
seen through a pose residual on the platform's tool and a point residual.
"""
from pathlib import Path

import numpy as np
import pinocchio as pin

from robocal import load_urdf
from robocal.systems.stewart.mechanism import StewartGeometry, inverse_kinematics_batch, random_workspace_poses
from robocal.model.parameters import ParameterSet, placement_parameters, offset_parameter
from robocal.estimation.problem import Problem
from robocal.testing import assert_problem_jacobian
from robocal.residuals import PointResidual, PoseResidual

URDF = Path(__file__).parents[1] / "urdf" / "stewart_6_6.urdf"


def stewart_problem(rng, n=4):
    robot = load_urdf(URDF)
    act = robot.loops.actuated
    ps = ParameterSet()
    for p in placement_parameters("base", "base", prefix="base"):
        ps.add(p)
    for j in range(1, 7):
        ps.add(offset_parameter(f"leg{j}_slide", "m"))
        for p in placement_parameters("joint_placement", f"leg{j}_u1"):
            ps.add(p)
        for p in placement_parameters("frame_placement", f"leg{j}_top.link2"):
            ps.add(p)
    for p in placement_parameters("frame_placement", "tool"):
        ps.add(p)
    for p in ps:
        p.value = rng.normal(0, 1e-3)
    geo = StewartGeometry.spec_6_6()
    R, p = random_workspace_poses(geo, n, rng)
    lengths = inverse_kinematics_batch(geo, R, p)
    return robot, ps, act, lengths


def test_pose_and_point_residuals_through_the_loops_match_finite_differences():
    rng = np.random.default_rng(0)
    robot, ps, act, lengths = stewart_problem(rng)
    n = len(lengths)
    meas = np.tile([0.0, 0.0, 0.4, 0.0, 0.0, 0.0, 1.0], (n, 1)) + rng.normal(0, 0.01, (n, 7))
    blocks = [PoseResidual("pose", "tool", np.arange(n), meas),
              PointResidual("pt", "platform", np.arange(n), rng.normal(0, 0.1, (n, 3)), point=(0.05, 0.02, 0.0))]
    problem = Problem(robot, ps, act, lengths, blocks)
    # h = 1e-5: the loops close to 1e-12, so assembly noise in the differences is ~1e-7; truncation ~h^2
    assert_problem_jacobian(problem, h=1e-5, tol=1e-6)


def test_joint_sensitivity_through_the_loops_matches_finite_differences():
    from robocal.model.kinematics import ModelState
    rng = np.random.default_rng(1)
    robot, ps, act, lengths = stewart_problem(rng, 1)
    ms = ModelState(robot, ps, act)
    s = ms.sample(lengths[0])
    J = s.frame_joint_jacobian("tool")
    M0 = s.pose("tool")
    h = 1e-5
    Jfd = np.zeros_like(J)
    for k in range(len(act)):
        for sgn in (1, -1):
            v = lengths[0].copy()
            v[k] += sgn * h
            Jfd[:, k] += sgn * pin.log6(M0.inverse() * ms.sample(v, q_guess=s.q).pose("tool")).vector / (2 * h)
    assert np.abs(J - Jfd).max() < 1e-6
