"""Closures as Pinocchio constraint models: rows from Pinocchio's constraint kinematics agree with robocal's own
formulas, and a Pinocchio model with its constraint models is a robocal robot.

Both row computations are exact formulas in double precision (no noise): they differ by rounding, ~1e-16 of the
rows' size (O(1) here). 1e-10 is the bar the issue sets; a wrong sign, frame or missing Jlog6 shows up as O(0.1).
"""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import robocal
from reference_evaluation import reference_evaluate
from robocal.errors import AssemblyError, InputError
from robocal.estimation.problem import Problem
from robocal.model.parameters import ParameterSet, offset_parameter, placement_parameters
from robocal.residuals import PoseResidual
from robocal.systems.stewart.mechanism import StewartGeometry, inverse_kinematics_batch, random_workspace_poses
from robocal.model.closure_groups import closure_groups, closure_state
from robocal.model.loop_rows import closure_rows
from robocal.model.loops import assemble
from robocal.model.pinocchio_robot import robot_from_pinocchio
from robocal.model.tree_arrays import TreeArrays

URDF = Path(__file__).resolve().parents[1] / "urdf"
AGREE = 1e-10
# a four-bar with one closure of each kind (rows: point 3, frame 6, distance 1, revolute 5): not a mechanism
# (over-constrained), only rows to compare at arbitrary configurations
KINDS = """<robot name="kinds">
  <link name="ground"/><link name="crank"/><link name="coupler"/><link name="rocker"/>
  <joint name="crank_joint" type="revolute"><parent link="ground"/><child link="crank"/><axis xyz="0 0 1"/>
    <limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
  <joint name="coupler_joint" type="continuous"><parent link="crank"/><child link="coupler"/>
    <origin xyz="0.1 0 0" rpy="0.1 0 0"/><axis xyz="0 0.6 0.8"/></joint>
  <joint name="rocker_joint" type="revolute"><parent link="ground"/><child link="rocker"/>
    <origin xyz="0.3 0 0" rpy="0 0.2 1.8"/><axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/>
  </joint>
  <loop_joint name="ball" type="spherical">
    <link1 link="coupler" xyz="0.3 0.01 0" rpy="0.3 0.2 0.1"/><link2 link="rocker" xyz="0.2 0 0.02"/></loop_joint>
  <loop_joint name="weld" type="fixed">
    <link1 link="coupler" xyz="0.3 0.1 0" rpy="0.1 0.2 0.3"/><link2 link="rocker" xyz="0.25 0 0.05" rpy="0 0 1"/>
  </loop_joint>
  <loop_joint name="bar" type="distance" length="0.3">
    <link1 link="crank" xyz="0.1 0 0"/><link2 link="rocker" xyz="0.25 0 0"/></loop_joint>
  <loop_joint name="hinge" type="revolute"><axis xyz="0 0 1"/>
    <link1 link="coupler" xyz="0.3 0 0"/><link2 link="rocker" xyz="0.2 0 0"/></loop_joint>
  <actuated joints="crank_joint"/>
</robot>"""


def robocal_rows(loops, model, q):
    """Today's rows (robocal.model.loop_rows on the anchor frames and their LOCAL Jacobians), every kind."""
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    c, jac = [], []
    for closure in loops.closures:
        i1, i2 = model.getFrameId(closure.frame1), model.getFrameId(closure.frame2)
        ck, d1, d2 = closure_rows(closure, data.oMf[i1], data.oMf[i2])
        c.append(ck)
        jac.append(d1 @ pin.getFrameJacobian(model, data, i1, pin.LOCAL)
                   + d2 @ pin.getFrameJacobian(model, data, i2, pin.LOCAL))
    return np.concatenate(c), np.vstack(jac)


def random_q(model, rng):
    return pin.integrate(model, pin.neutral(model), rng.normal(0.0, 0.6, model.nv))


def test_pinocchio_rows_agree_with_robocal_rows_for_every_kind(tmp_path):
    path = tmp_path / "kinds.urdf"
    path.write_text(KINDS)
    robot = robocal.load_urdf(path)
    loops, model = robot.loops, robot.model
    assert [c.kind for c in loops.closures] == ["point", "frame", "distance", "revolute"]
    rows = loops.pinocchio_rows(model)
    assert [type(cm.extract()).__name__ for cm in rows.constraints] == ["PointAnchorConstraintModel",
                                                                      "FrameAnchorConstraintModel"]
    rng = np.random.default_rng(3)
    for _ in range(10):      # off the constraint manifold: every row non-zero
        q = random_q(model, rng)
        c, jac = loops.constraint_jacobian(model, model.createData(), q)
        c_ref, jac_ref = robocal_rows(loops, model, q)
        assert np.abs(c).max() > 0.01
        np.testing.assert_allclose(c, c_ref, rtol=0, atol=AGREE)
        np.testing.assert_allclose(jac, jac_ref, rtol=0, atol=AGREE)
        np.testing.assert_allclose(loops.constraint_error(model, model.createData(), q), c_ref, rtol=0, atol=AGREE)


def test_pinocchio_rows_jacobian_matches_finite_differences(tmp_path):
    """d c / d v by central differences through pin.integrate: step 1e-6, truncation ~1e-12 * |c'''|, rounding
    ~1e-16 / 1e-6: agreement to 1e-7 for O(1) rows."""
    path = tmp_path / "kinds.urdf"
    path.write_text(KINDS)
    robot = robocal.load_urdf(path)
    loops, model = robot.loops, robot.model
    q = random_q(model, np.random.default_rng(7))
    _, jac = loops.constraint_jacobian(model, model.createData(), q)
    h, fd = 1e-6, np.empty_like(jac)
    for k in range(model.nv):
        dv = np.zeros(model.nv)
        dv[k] = h
        plus = loops.constraint_error(model, model.createData(), pin.integrate(model, q, dv))
        minus = loops.constraint_error(model, model.createData(), pin.integrate(model, q, -dv))
        fd[:, k] = (plus - minus) / (2 * h)
    np.testing.assert_allclose(jac, fd, rtol=0, atol=1e-7)


def test_batched_rows_agree_with_pinocchio_rows_on_the_stewart_platform():
    """The batched path's whole-array rows (robocal.model.closure_groups) against Pinocchio's, sample by sample."""
    robot = robocal.load_urdf(URDF / "stewart_6_6.urdf")
    model, loops = robot.model, robot.loops
    rng = np.random.default_rng(5)
    q = np.array([pin.integrate(model, pin.neutral(model), rng.normal(0, 0.05, model.nv)) for _ in range(8)])
    tree = TreeArrays(model)
    state = closure_state(tree, closure_groups(model, loops, tree), loops.n_rows, loops.solved_v, q)
    for i, qi in enumerate(q):
        c, jac = loops.constraint_jacobian(model, model.createData(), qi)
        np.testing.assert_allclose(state["c"][i], c, rtol=0, atol=AGREE)
        np.testing.assert_allclose(state["Cs"][i], jac[:, loops.solved_v], rtol=0, atol=AGREE)


def stewart_from_constraint_models(kind: str = "concrete"):
    """The Stewart platform's tree (its URDF without the loop elements) and six point-anchor constraint models built
    in Python from the URDF's anchors, as a Pinocchio user would hand them to robocal."""
    urdf = robocal.load_urdf(URDF / "stewart_6_6.urdf")
    tree = pin.buildModelFromUrdf(str(URDF / "stewart_6_6.urdf"))
    models = pin.StdVec_ConstraintModel() if kind == "generic" else []
    for closure in urdf.loops.closures:
        f1, f2 = (urdf.model.frames[urdf.frame_id(n)] for n in (closure.frame1, closure.frame2))
        j1, j2 = tree.getJointId(urdf.model.names[f1.parentJoint]), tree.getJointId(urdf.model.names[f2.parentJoint])
        if kind == "rigid":
            cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, tree, j1, f1.placement, j2, f2.placement)
        else:
            cm = pin.PointAnchorConstraintModel(tree, j1, f1.placement, j2, f2.placement)
        cm.name = closure.name
        models.append(cm)
    return urdf, robot_from_pinocchio(tree, models, actuated=urdf.loops.actuated, name="stewart")


@pytest.mark.parametrize("kind", ["concrete", "generic", "rigid"])
def test_a_pinocchio_model_with_constraint_models_assembles_as_the_urdf(kind):
    urdf, robot = stewart_from_constraint_models(kind)
    assert [c.name for c in robot.loops.closures] == [c.name for c in urdf.loops.closures]
    assert robot.loops.actuated == urdf.loops.actuated and robot.loops.passive == urdf.loops.passive
    for closure in robot.loops.closures:     # anchors where the URDF puts them (parameter names and meaning too)
        for name in (closure.frame1, closure.frame2):
            a, b = robot.model.frames[robot.frame_id(name)], urdf.model.frames[urdf.frame_id(name)]
            assert robot.model.names[a.parentJoint] == urdf.model.names[b.parentJoint]
            np.testing.assert_allclose(a.placement.homogeneous, b.placement.homogeneous, atol=1e-15)
    struts = [0.02, -0.01, 0.03, 0.0, 0.01, -0.02]
    q1, q2 = assemble(robot, robot.model, struts), assemble(urdf, urdf.model, struts)
    tool = [m.frames[r.frame_id("tool")] for r, m in ((robot, robot.model), (urdf, urdf.model))]
    poses = []
    for r, q in ((robot, q1), (urdf, q2)):
        data = r.model.createData()
        pin.framesForwardKinematics(r.model, data, q)
        poses.append(data.oMf[r.frame_id("tool")].homogeneous.copy())
    assert tool[0].parentJoint == robot.joint_id("platform_float")
    np.testing.assert_allclose(poses[0], poses[1], atol=1e-12)     # both assembled to 1e-12


def test_bad_constraint_models_are_named():
    urdf = robocal.load_urdf(URDF / "stewart_6_6.urdf")
    small = pin.buildModelFromUrdf(str(URDF / "stewart_6_6.urdf"))
    big = pin.Model(small)
    for k in range(3):
        big.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), f"extra{k}")
    cm = pin.PointAnchorConstraintModel(big, big.getJointId("extra2"), pin.SE3.Identity(), 1, pin.SE3.Identity())
    cm.name = "stray"
    with pytest.raises(InputError, match=r"constraint 'stray' \(#1\): joint1_id = 22 is not a joint of the model"):
        robot_from_pinocchio(small, [cm], actuated=urdf.loops.actuated)
    contact = pin.PointContactConstraintModel(small, 1, pin.SE3.Identity())
    with pytest.raises(InputError, match="PointContactConstraintModel; robocal reads point and frame anchors"):
        robot_from_pinocchio(small, [contact], actuated=urdf.loops.actuated)
    ok = pin.PointAnchorConstraintModel(small, 3, pin.SE3.Identity(), 19, pin.SE3.Identity())
    with pytest.raises(InputError, match="actuated joint 'leg9_slide' is not a joint of the model"):
        robot_from_pinocchio(small, [ok], actuated=["leg9_slide"])


def test_a_loop_that_cannot_close_names_file_loop_and_sample():
    robot = robocal.load_urdf(URDF / "stewart_6_6.urdf")
    with pytest.raises(AssemblyError) as info:
        assemble(robot, robot.model, [0.8, -0.8, 0.8, -0.8, 0.8, -0.8], sample=17)   # struts far out of reach
    message = str(info.value)
    assert message.startswith(str(URDF / "stewart_6_6.urdf") + ": sample 17: closed-chain assembly")
    assert info.value.sample == 17 and info.value.constraint.startswith("leg")
    assert f"loop '{info.value.constraint}' is the furthest from closed" in message


@pytest.mark.parametrize("components", [("tx", "ty"), ("tx", "ty", "tz", "rx", "ry", "rz"), ("rx",)])
def test_batched_jacobian_of_point_closures_first_anchors(components):
    """A point closure's first anchor (`<closure>.link1`) with any subset of its six components: the batched
    path's parameter rows against the per-sample reference (it once indexed the components' axis wrongly, which
    only translation triples survived). Rounding only: 1e-10 relative."""
    def make():
        rng = np.random.default_rng(0)
        robot = robocal.load_urdf(URDF / "stewart_6_6.urdf")
        params = ParameterSet()
        for j in range(1, 7):
            for p in placement_parameters("frame_placement", f"leg{j}_top.link1", components):
                params.add(p)
            params.add(offset_parameter(f"leg{j}_slide", "m"))
        for p in params:
            p.value = rng.normal(0, 1e-3)
        geo, n = StewartGeometry.spec_6_6(), 6
        R, p = random_workspace_poses(geo, n, rng)
        quats = np.array([pin.Quaternion(pin.exp3(rng.normal(0, 0.3, 3))).coeffs() for _ in range(n)])
        measured = np.hstack([rng.normal(0, 0.05, (n, 3)) + [0, 0, 0.4], quats])
        return Problem(robot, params, robot.loops.actuated, inverse_kinematics_batch(geo, R, p),
                       [PoseResidual("pose", "tool", np.arange(n), measured)])
    batched, reference = make().evaluate(), reference_evaluate(make())
    assert np.abs(batched.J - reference.J).max() < 1e-10 * np.abs(reference.J).max()
    assert np.abs(reference.J).max() > 0.1


def test_desired_offsets_of_constraint_models():
    """A point anchor's desired offset is folded into its first anchor (the same residual, to rounding); a frame
    anchor's is refused by name."""
    model = pin.Model()
    crank = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "crank")
    finger = model.addJoint(crank, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array([0, 0.06, 0])), "finger")
    rocker = model.addJoint(0, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array([0.02, 0, 0])), "rocker")
    cm = pin.PointAnchorConstraintModel(model, finger, pin.SE3(np.eye(3), np.array([0.02, 0, 0])),
                                        rocker, pin.SE3(np.eye(3), np.array([0, 0.06, 0])))
    cm.desired_constraint_offset = np.array([0.01, -0.02, 0.003])
    data, cd, q = model.createData(), cm.createData(), np.array([0.3, -0.2, 0.1])
    pin.computeJointJacobians(model, data, q)
    cm.calc(model, data, cd)
    robot = robot_from_pinocchio(model, [cm], actuated=["crank"])
    np.testing.assert_allclose(robot.loops.constraint_error(robot.model, robot.model.createData(), q),
                               cd.constraint_position_error, atol=1e-15)
    weld = pin.FrameAnchorConstraintModel(model, finger, pin.SE3.Identity(), rocker, pin.SE3.Identity())
    weld.name = "w"
    weld.desired_constraint_offset = np.full(6, 0.01)
    with pytest.raises(InputError, match="constraint 'w' \\(#1\\) has a desired_constraint_offset"):
        robot_from_pinocchio(model, [weld], actuated=["crank"])


def test_urdf_loops_as_pinocchio_constraint_models_round_trip():
    """robot.constraint_models() gives the URDF closures as Pinocchio constraint models; handed back with the
    model, they make the same robot (the anchor frames already there are reused)."""
    robot = robocal.load_urdf(URDF / "stewart_6_6.urdf")
    models = robot.constraint_models()
    assert [cm.name for cm in models] == [c.name for c in robot.loops.closures]
    assert {type(cm.extract()).__name__ for cm in models} == {"PointAnchorConstraintModel"}
    again = robot_from_pinocchio(robot.model, models, actuated=robot.loops.actuated)
    assert again.model.nframes == robot.model.nframes
    q = assemble(robot, robot.model, [0.01] * 6)
    np.testing.assert_allclose(again.loops.constraint_error(again.model, again.model.createData(), q),
                               robot.loops.constraint_error(robot.model, robot.model.createData(), q), atol=1e-15)
