"""Closure derivatives against central finite differences (off the constraint manifold)."""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.model.loop_rows import Closure
from robocal.model.loops import LoopSet

URDF = Path(__file__).resolve().parents[1] / "urdf"
EPS = 1e-6
# central differences: truncation ~ EPS^2 * |c'''| ~ 1e-12, round-off ~ 1e-16 / EPS ~ 1e-10
FD_TOL = 1e-8


def closure_set(kind):
    """A LoopSet with one closure of `kind` on two frames of a tiny model (only closure_error is used)."""
    model = pin.Model()
    model.addFrame(pin.Frame("a", 0, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    model.addFrame(pin.Frame("b", 0, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    axis = tuple(np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])) if kind == "revolute" else None
    rows = {"point": 3, "frame": 6, "distance": 1, "revolute": 5}[kind]
    return LoopSet(model, [Closure("k", kind, "a", "b", rows, 0.4, axis)], [])


@pytest.mark.parametrize("kind", ["point", "frame", "distance", "revolute"])
def test_closure_error_derivatives_match_finite_differences(kind):
    rng = np.random.default_rng(3)
    loops = closure_set(kind)
    for _ in range(5):
        M1, M2 = pin.exp6(rng.normal(0, 1, 6)), pin.exp6(rng.normal(0, 1, 6))
        c, D1, D2 = loops.closure_error([M1], [M2])
        assert c.shape == (loops.n_rows,) and D1[0].shape == D2[0].shape == (loops.n_rows, 6)
        for which, D in ((0, D1[0]), (1, D2[0])):
            fd = np.empty_like(D)
            for i in range(6):
                xi = np.zeros(6)
                xi[i] = EPS
                plus = [M1 * pin.exp6(xi), M2] if which == 0 else [M1, M2 * pin.exp6(xi)]
                minus = [M1 * pin.exp6(-xi), M2] if which == 0 else [M1, M2 * pin.exp6(-xi)]
                fd[:, i] = (loops.closure_error([plus[0]], [plus[1]])[0]
                            - loops.closure_error([minus[0]], [minus[1]])[0]) / (2 * EPS)
            assert np.abs(fd - D).max() < FD_TOL, (kind, which)


def test_closure_values_follow_the_documented_formulas():
    rng = np.random.default_rng(4)
    M1, M2 = pin.exp6(rng.normal(0, 1, 6)), pin.exp6(rng.normal(0, 1, 6))
    c_point = closure_set("point").closure_error([M1], [M2])[0]
    np.testing.assert_allclose(c_point, M1.rotation.T @ (M2.translation - M1.translation), atol=1e-14)
    c_frame = closure_set("frame").closure_error([M1], [M2])[0]
    np.testing.assert_allclose(c_frame, pin.log6(M1.inverse() * M2).vector, atol=1e-14)
    c_dist = closure_set("distance").closure_error([M1], [M2])[0]
    np.testing.assert_allclose(c_dist, [np.linalg.norm(M2.translation - M1.translation) - 0.4], atol=1e-14)


def constraint_fd(loops, model, data, q):
    """Central differences of the closure rows along each velocity coordinate (q <- integrate(q, v))."""
    fd = np.empty((loops.n_rows, model.nv))
    for i in range(model.nv):
        dv = np.zeros(model.nv)
        dv[i] = EPS
        fd[:, i] = (loops.constraint_error(model, data, pin.integrate(model, q, dv))
                    - loops.constraint_error(model, data, pin.integrate(model, q, -dv))) / (2 * EPS)
    return fd


@pytest.mark.parametrize("name", ["stewart_6_6", "stewart_3_3"])
def test_constraint_jacobian_matches_finite_differences_through_the_model(name):
    robot = robocal.load_urdf(URDF / f"{name}.urdf")
    model, loops = robot.model, robot.loops
    data = model.createData()
    rng = np.random.default_rng(7)
    q = pin.integrate(model, pin.neutral(model), rng.normal(0, 0.1, model.nv))  # not assembled
    c, jac = loops.constraint_jacobian(model, data, q)
    assert jac.shape == (loops.n_rows, model.nv) and np.abs(c).max() > 1e-3
    assert np.abs(constraint_fd(loops, model, data, q) - jac).max() < FD_TOL


MIXED = """<robot name="mixed">
  <link name="ground"/><link name="a"/><link name="b"/><link name="c"/>
  <joint name="ja" type="revolute"><parent link="ground"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
  <joint name="jb" type="continuous"><parent link="a"/><child link="b"/><origin xyz="0.1 0 0" rpy="0.3 0 0"/>
    <axis xyz="0 1 1"/></joint>
  <joint name="jc" type="prismatic"><parent link="ground"/><child link="c"/><origin xyz="0.3 0.1 0"/>
    <axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <loop_joint name="k1" type="spherical"><link1 link="b" xyz="0.3 0 0"/><link2 link="c" xyz="0.2 0 0.1"/></loop_joint>
  <loop_joint name="k2" type="fixed"><link1 link="b" xyz="0.1 0.2 0" rpy="0.1 0.2 0.3"/><link2 link="c"/></loop_joint>
  <!-- MORE -->
</robot>"""


@pytest.mark.parametrize("kinds", [
    ('type="distance" length="0.3"', 'type="revolute"'),
    ('type="revolute"', 'type="spherical"'),
])
def test_mixed_closure_kinds_stack_their_rows_in_order(tmp_path, kinds):
    text = MIXED.replace("<!-- MORE -->",
                         f'<loop_joint name="k3" {kinds[0]}><axis xyz="0 0.6 0.8"/><link1 link="a" xyz="0.1 0 0"/>'
                         f'<link2 link="c"/></loop_joint>'
                         f'<loop_joint name="k4" {kinds[1]}><axis xyz="1 0 0"/><link1 link="ground"/>'
                         f'<link2 link="b" xyz="0 0.1 0"/></loop_joint><actuated joints="ja"/>')
    path = tmp_path / "mixed.urdf"
    path.write_text(text)
    robot = robocal.load_urdf(path)
    model, loops = robot.model, robot.loops
    data = model.createData()
    q = pin.integrate(model, pin.neutral(model), np.random.default_rng(8).normal(0, 0.5, model.nv))
    c, jac = loops.constraint_jacobian(model, data, q)
    np.testing.assert_allclose(c, loops.constraint_error(model, data, q), atol=1e-15)
    assert np.abs(constraint_fd(loops, model, data, q) - jac).max() < FD_TOL
