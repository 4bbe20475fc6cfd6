"""Contact residuals that the other tests do not simulate: cylinder (hole and pin) and laser line."""
import numpy as np
import pinocchio as pin

from robocal import load_example
from robocal.estimation.calibrate import calibrate
from robocal.model.parameters import robot_parameters
from robocal.estimation.problem import Problem
from robocal.residuals import CylinderResidual, LaserLineResidual
from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from synthetic_cases import identifiable_names


def test_cylinder_and_laser_line_noise_free_recovery():
    rng = np.random.default_rng(31)
    robot = load_example("ur5")
    robot.add_frame("probe", "tool0", pin.SE3(np.eye(3), np.array([0.01, 0.02, 0.12])))
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "offsets")
    n = 30
    values = random_configurations(robot, joints, 3 * n, rng, span=0.6)
    s = np.arange(3 * n)
    blocks = [
        CylinderResidual("bore", "probe", s[:n], axis_point=(0.4, 0.1, 0.2), axis_direction=(0.05, 0.0, 1.0),
                         radius=0.02, inside=True, tip_radius=0.003, sigma=1e-12),
        CylinderResidual("pin", "probe", s[n:2 * n], axis_point=(0.3, -0.3, 0.25), axis_direction=(1.0, 0.1, 0.0),
                         radius=0.01, inside=False, tip_radius=0.003, sigma=1e-12),
        LaserLineResidual("psd", "tool0", s[2 * n:], target=(0.5, 0.2, 0.3), direction=(0.0, 0.0, 1.0), sigma=1e-12),
    ]
    problem = Problem(robot, params, joints, values, blocks)
    names = identifiable_names(problem)
    truth = perturb(problem.params, rng, 0, np.radians(0.2), patterns=[n for n in names if "joint" in n])
    simulate_measurements(problem, truth, rng)
    ev = problem.evaluate(jacobian=False)
    assert np.abs(ev.raw).max() > 1e-4            # the nominal model does not satisfy the contacts
    for p in problem.params:                       # start the set-ups away from the truth
        if p.kind == "auxiliary" and p.vary:
            p.value += 2e-3 if p.unit == "m" else 0.01
    result = calibrate(problem)
    assert result.success
    assert max(abs(problem.params[n].value - truth[n].value) for n in names) < 1e-9
