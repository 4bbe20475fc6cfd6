"""Stewart measuring modes: orientation conventions, input checks, the new residuals' Jacobians against
finite differences (spec §6.5 test 2, with the printed '+' typo of Eq. 7 shown to fail), and the generic
closed-loop FK against the closed-form IK on 1000 poses."""
import numpy as np
import pinocchio as pin
import pytest

from robocal.errors import InputError
from robocal.model.loops import assemble
from robocal.systems.stewart import mechanism as st
from robocal.estimation.problem import Problem
from robocal.systems.stewart import calibration as sc
from robocal.systems.stewart import modes as sm
from robocal.systems.stewart.two_stage import ik_problem
from test_stewart_calibration_recovery import TOOL, robot, truth_params  # noqa: F401 (fixture)


@pytest.mark.parametrize("convention", sm.CONVENTIONS)
def test_pose_rows_round_trip_through_quaternions(convention):
    rng = np.random.default_rng(0)
    rows = np.column_stack([rng.normal(size=(20, 3)), rng.uniform(-1.2, 1.2, (20, 3))])
    back = sm.xyzquat_to_pose_rows(sm.pose_rows_to_xyzquat(rows, convention), convention)
    assert np.abs(back - rows).max() < 1e-12


def test_default_convention_is_rx_ry_rz_and_differs_from_rpy():
    abc = np.array([0.3, -0.2, 0.5])
    assert np.abs(sm.rotation(abc) - st.rotation_xyz(abc)).max() < 1e-15
    assert np.abs(sm.rotation(abc, "zyx_rpy") - pin.rpy.rpyToMatrix(*abc)).max() < 1e-15
    assert np.abs(sm.rotation(abc) - sm.rotation(abc, "zyx_rpy")).max() > 1e-2
    # with Rx Ry Rz the tool axis R e_z does not depend on C (claim 5)
    assert np.abs(sm.rotation([0.3, -0.2, 0.0])[:, 2] - sm.rotation(abc)[:, 2]).max() < 1e-15


def test_bad_input_names_row_and_field(robot):
    rows = np.zeros((3, 6))
    rows[1, 4] = np.nan
    with pytest.raises(InputError, match="row 2.*column 5"):
        sm.pose_rows_to_xyzquat(rows, source="poses.csv")
    with pytest.raises(InputError, match="convention"):
        sm.rotation([0, 0, 0], "zxz")
    u = np.ones((3, 6))
    u[2, 0] = -1
    with pytest.raises(InputError, match="row 3.*'u'"):
        sm.pose_residuals("p", robot, np.arange(3), np.zeros((3, 6)), u, TOOL)
    with pytest.raises(InputError, match="weigh A and B equally"):
        sm.pose_residuals("p", robot, np.arange(3), np.zeros((3, 6)), [1, 1, 1, 1, 2, 0], TOOL)
    with pytest.raises(InputError, match="kind"):
        sm.cylinder_residual("c", [0], (0, 0, 0), (0, 0, 1), 0.01, TOOL, kind="slot")


def _fd(problem, h=1e-6, typo=False):
    """Relative error of the analytic Jacobian against Eq. 7, (g(x2) - g(x1)) / e with e = 2h; with
    typo=True the spec's printed "+" version (g(x2) + g(x1)) / e."""
    ev = problem.evaluate()
    x0 = problem.params.free_values()
    J = np.zeros_like(ev.J)
    for j in range(len(x0)):
        for sgn in (1, -1):
            x = x0.copy()
            x[j] += sgn * h
            problem.params.set_free_values(x)
            J[:, j] += (1 if typo else sgn) * problem.evaluate(jacobian=False).r / (2 * h)
    problem.params.set_free_values(x0)
    return np.abs(ev.J - J).max() / np.abs(ev.J).max()


def test_tool_axis_and_pose_jacobians_through_the_loops_match_central_differences(robot):
    rng = np.random.default_rng(2)
    truth = truth_params(rng)
    tips = sc.random_tips(3, rng)
    abc, R = sc.random_orientations(3, rng)
    s = sc.struts(sc.geometry(robot, truth), sc.tip_to_platform(tips, R, TOOL))
    rows = np.column_stack([tips, abc]) + rng.normal(0, 1e-3, (3, 6))
    blocks = sm.pose_residuals("p", robot, np.arange(3), rows, [[1, 1, 1, 1, 1, 1], [1, 1, 1, 1, 1, 0],
                                                                 [0, 0, 0, 1, 1, 0]], TOOL, (1e-5, 1e-5))
    assert [b.type_name for b in blocks] == ["pose", "pose", "tool_axis", "tool_axis"]
    params = sc.stewart_parameters()
    for p in params:
        p.value = rng.normal(0, 1e-3)
    problem = Problem(robot, params, sc.actuated(robot), s, blocks)
    # h = 1e-6 m: truncation ~h^2 = 1e-12 relative; the loops close to 1e-12 m, i.e. 1e-6 after / h
    assert _fd(problem) < 1e-5
    assert _fd(problem, typo=True) > 1e-1          # the printed "(g(x2) + g(x1)) / e" is not a derivative


def test_strut_ik_residual_jacobian_matches_central_differences(robot):
    rng = np.random.default_rng(3)
    truth = truth_params(rng, sigma=0.05)
    tips = sc.random_tips(3, rng)
    abc, R = sc.random_orientations(3, rng)
    s = sc.struts(sc.geometry(robot, truth), sc.tip_to_platform(tips, R, TOOL))
    params = sc.stewart_parameters()
    for p in params:
        p.value = rng.normal(0, 0.05)
    problem = ik_problem(robot, params, np.column_stack([tips, abc]), s, TOOL)
    assert np.abs(problem.evaluate().r).max() > 1.0   # far from the truth (sigma 1e-5 m): a real test
    assert _fd(problem) < 1e-7                         # tree kinematics only: no assembly noise
    # at the truth the IK residual vanishes
    for p in truth:
        params[p.name].value = p.value
    assert np.abs(problem.evaluate(jacobian=False).raw).max() < 1e-12


def test_generic_closed_loop_fk_agrees_with_closed_form_ik_on_1000_poses(robot):
    geo = st.StewartGeometry.spec_6_6()
    R, p = st.random_workspace_poses(geo, 1000, np.random.default_rng(11))
    s = st.inverse_kinematics_batch(geo, R, p)
    data = robot.model.createData()
    q, worst = None, 0.0
    for k in range(1000):
        q = assemble(robot, robot.model, s[k], q_guess=q, sample=k, data=data)
        M = st.platform_pose(robot, robot.model, q, data)
        worst = max(worst, np.linalg.norm(pin.log6(M.actInv(pin.SE3(R[k], p[k]))).vector))
    assert worst < 1e-10


def test_tool_axis_rows_are_the_two_tilt_angles_and_simulated_noise_matches_sigma():
    from robocal.residuals.tool_axis import ToolAxisResidual

    class State:                                   # just what the residual asks of a sample
        def __init__(self, M):
            self.M = M

        def pose(self, frame):
            return self.M

    rng = np.random.default_rng(4)
    Rs = [pin.exp3(rng.normal(size=3)) for _ in range(400)]
    states = [State(pin.SE3(R, np.zeros(3))) for R in Rs]
    measured = []
    for R in Rs:
        e = R[:, 2]
        n = np.cross(e, [1.0, 0.0, 0.0]); n /= np.linalg.norm(n)
        measured.append(pin.exp3(2e-3 * n) @ e)    # 2 mrad away from the model's axis
    res = ToolAxisResidual("a", "tool", np.arange(400), measured, sigma=1e-3)
    r = np.array([res.evaluate(k, states, None).r for k in range(400)])
    assert r.shape == (400, 2)                     # two rows: the along-axis one carries no information
    np.testing.assert_allclose(np.linalg.norm(r, axis=1), np.sin(2e-3), rtol=1e-9)
    # noise-free simulation gives zero rows; with noise each row has variance sigma^2 (so chi^2 / dof ~ 1)
    sim = np.array([res.simulate(k, states, None, rng) for k in range(400)])
    noisy = ToolAxisResidual("a", "tool", np.arange(400), sim, sigma=1e-3)
    r = np.array([noisy.evaluate(k, states, None).r for k in range(400)])
    # 800 rows: the sample variance of sigma^2 has a relative sd of sqrt(2/800) = 5 %; 4 sd = 20 %
    assert abs(np.mean(r ** 2) / 1e-6 - 1.0) < 0.2
