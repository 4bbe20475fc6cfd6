"""The batched closed-chain path (robocal.model.closed_chain_batch) against the plain per-sample reference.

tests/reference_evaluation.py walks every sample through SampleState: damped Newton assembly from the
warm start, then implicit-function derivatives through the closures, sample by sample. The batched path
takes the same damped steps from the same warm starts and evaluates the same formulas in another order, so
the two differ by rounding only (measured ~2e-13 relative on the residuals, ~1e-14 on the Jacobian); 1e-10
relative is the bar set for it (robocal issue 20), while a wrong sign, frame or column shows up as O(1).
"""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import robocal
from reference_evaluation import reference_evaluate
from robocal.errors import AssemblyError
from robocal.estimation.problem import Problem
from robocal.model.closed_chain_batch import supports_closed_batch
from robocal.model.closure_arrays import closure_arrays, hinge_bases
from robocal.model.closure_groups import closure_groups, closure_state
from robocal.model.kinematics import ModelState
from robocal.model.loop_rows import Closure, closure_rows
from robocal.model.parameters import ParameterSet, offset_parameter, placement_parameters
from robocal.model.point_closure_solve import PointArrow
from robocal.model.tree_arrays import TreeArrays
from robocal.residuals import PointResidual, PoseResidual
from robocal.systems.stewart.mechanism import StewartGeometry, inverse_kinematics_batch, random_workspace_poses
from robocal.testing import assert_problem_jacobian

URDF = Path(__file__).resolve().parents[1] / "urdf"
RTOL = 1e-10
# A crank-rocker four-bar closed by a revolute closure (5 rows, two of them redundant in the plane: more rows
# than unknowns) and an arm tied to the coupler by a distance closure; the coupler joint is continuous.
LINKAGE = """<robot name="linkage">
  <link name="ground"/><link name="crank"/><link name="coupler"/><link name="rocker"/><link name="arm"/>
  <link name="tip"/>
  <joint name="crank_joint" type="revolute"><parent link="ground"/><child link="crank"/><axis xyz="0 0 1"/>
    <limit lower="-7" upper="7" effort="1" velocity="1"/></joint>
  <joint name="coupler_joint" type="continuous"><parent link="crank"/><child link="coupler"/>
    <origin xyz="0.1 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="rocker_joint" type="revolute"><parent link="ground"/><child link="rocker"/>
    <origin xyz="0.3 0 0" rpy="0 0 1.8"/><axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/>
  </joint>
  <joint name="arm_joint" type="revolute"><parent link="ground"/><child link="arm"/>
    <origin xyz="0 0.3 0" rpy="0 0 -0.5"/><axis xyz="0 0 1"/><limit lower="-7" upper="7" effort="1" velocity="1"/>
  </joint>
  <joint name="tip_joint" type="fixed"><parent link="coupler"/><child link="tip"/><origin xyz="0.2 0.05 0"/></joint>
  <loop_joint name="hinge" type="revolute"><axis xyz="0 0 1"/>
    <link1 link="coupler" xyz="0.3 0 0"/><link2 link="rocker" xyz="0.2 0 0"/></loop_joint>
  <loop_joint name="rod" type="distance" length="0.2">
    <link1 link="arm" xyz="0.25 0 0"/><link2 link="coupler" xyz="0.15 0 0"/></loop_joint>
  <actuated joints="crank_joint"/>
</robot>"""


def _quaternions(rng, n):
    return np.array([pin.Quaternion(pin.exp3(rng.normal(0, 0.3, 3))).coeffs() for _ in range(n)])


def _add(ps, params):
    for p in params:
        ps.add(p)


def stewart_problem(seed=0, n=10):
    """Stewart 6-6 with every parameter kind the closures see: base-joint placements (all six components),
    platform anchors (all six), strut offsets, plus a tool frame and the base; a pose and a point residual."""
    rng = np.random.default_rng(seed)
    robot = robocal.load_urdf(URDF / "stewart_6_6.urdf")
    ps = ParameterSet()
    _add(ps, placement_parameters("base", "base", prefix="base"))
    for j in range(1, 7):
        ps.add(offset_parameter(f"leg{j}_slide", "m"))
        _add(ps, placement_parameters("joint_placement", f"leg{j}_u1"))
        _add(ps, placement_parameters("frame_placement", f"leg{j}_top.link2"))
    _add(ps, placement_parameters("frame_placement", "tool"))
    for p in ps:
        p.value = rng.normal(0, 1e-3)
    geo = StewartGeometry.spec_6_6()
    R, p = random_workspace_poses(geo, n, rng)
    lengths = inverse_kinematics_batch(geo, R, p)
    s = np.arange(n)
    residuals = [PoseResidual("pose", "tool", s, np.hstack([rng.normal(0, 0.05, (n, 3)) + [0, 0, 0.4],
                                                            _quaternions(rng, n)])),
                 PointResidual("point", "platform", s[::2], rng.normal(0, 0.1, (len(s[::2]), 3)),
                               point=(0.05, 0.02, 0.0))]
    return Problem(robot, ps, robot.loops.actuated, lengths, residuals)


def linkage_problem(tmp_path, seed=0, n=10):
    """The linkage with placements, anchors, an offset, the base and a tool frame free (all in the plane, so
    the loops still close), a pose residual on the tool and a point residual on the arm."""
    rng = np.random.default_rng(seed)
    path = tmp_path / "linkage.urdf"
    path.write_text(LINKAGE)
    robot = robocal.load_urdf(path)
    ps = ParameterSet()
    _add(ps, placement_parameters("base", "base", ("tx", "ty", "rz"), prefix="base"))
    _add(ps, placement_parameters("joint_placement", "rocker_joint", ("tx", "ty", "rz")))
    _add(ps, placement_parameters("joint_placement", "arm_joint", ("tx", "ty")))
    _add(ps, placement_parameters("frame_placement", "hinge.link2", ("tx", "ty")))
    _add(ps, placement_parameters("frame_placement", "rod.link1", ("tx", "ty")))
    _add(ps, placement_parameters("frame_placement", "tip", ("tx", "ty", "rz")))
    ps.add(offset_parameter("crank_joint", "rad"))
    for p in ps:
        p.value = rng.normal(0, 1e-3)
    crank = np.linspace(0.2, 1.5, n)[:, None]
    measured = np.hstack([rng.normal(0, 0.1, (n, 3)), _quaternions(rng, n)])
    # the arm moves only through the distance closure: a point on it makes that closure's rows count
    return Problem(robot, ps, ["crank_joint"], crank, [
        PoseResidual("tip", "tip", np.arange(n), measured),
        PointResidual("arm", "arm", np.arange(n), rng.normal(0, 0.1, (n, 3)), point=(0.1, 0.02, 0.0))])


def _relative(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


def _compare_two_passes(make):
    """Batched and per-sample evaluation, each on its own problem (own warm starts): the first pass from the
    neutral configuration, then a second from the first's solutions after a parameter step."""
    batched, plain = make(), make()
    assert supports_closed_batch(batched.model_state())
    step = np.random.default_rng(9).normal(0, 1e-4, len(batched.params.free_names))
    for k in range(2):
        if k:
            for problem in (batched, plain):
                problem.params.set_free_values(problem.params.free_values() + step)
        a, b = batched.evaluate(), reference_evaluate(plain)
        assert _relative(a.r, b.r) < RTOL and _relative(a.raw, b.raw) < RTOL
        assert _relative(a.J, b.J) < RTOL
        assert np.array_equal(a.group, b.group)
        assert np.abs(a.J).max() > 1.0      # the comparison is not between zeros


def test_stewart_batched_matches_the_per_sample_reference():
    _compare_two_passes(stewart_problem)


def test_revolute_and_distance_closures_match_the_per_sample_reference(tmp_path):
    _compare_two_passes(lambda: linkage_problem(tmp_path))


def test_linkage_jacobian_matches_finite_differences(tmp_path):
    # h = 1e-5: the loops close to 1e-12, so assembly noise in the differences is ~1e-12 / 1e-5 = 1e-7 of a
    # sigma-scaled row per unit; truncation ~h^2 = 1e-10. tol 1e-6 sits above both.
    assert_problem_jacobian(linkage_problem(tmp_path, n=6), h=1e-5, tol=1e-6)


def test_stewart_jacobian_with_tool_and_base_matches_finite_differences():
    # as above: assembly noise ~1e-7, truncation ~1e-10
    assert_problem_jacobian(stewart_problem(n=3), h=1e-5, tol=1e-6)


def test_unreachable_readings_raise_an_assembly_error_naming_the_sample():
    problem = stewart_problem(n=4)
    problem.values[2, 0] += 2.0        # one strut 2 m longer than the others: no assembly
    with pytest.raises(AssemblyError, match="sample 2"):
        problem.evaluate()


def test_samples_no_residual_looks_at_are_not_assembled():
    """As on the per-sample path: an unreachable sample that no term uses does not stop the evaluation."""
    problem = stewart_problem(n=4)
    problem.values = np.vstack([problem.values, problem.values[:1] + [2.0, 0, 0, 0, 0, 0]])
    ev = problem.evaluate()
    assert 4 not in problem.warm_starts and np.isfinite(ev.J).all()


def test_joint_relations_keep_the_per_sample_path():
    robot = robocal.load_urdf(URDF / "floating_nut_hexapod.urdf")
    assert robot.loops.relations
    assert not supports_closed_batch(ModelState(robot, ParameterSet(), robot.loops.actuated))


def _models(tmp_path):
    path = tmp_path / "linkage.urdf"
    path.write_text(LINKAGE)
    models = [robocal.load_urdf(URDF / name).model for name in
              ("stewart_6_6.urdf", "floating_nut_hexapod.urdf", "pcmm_4puu.urdf")]
    models.append(robocal.load_urdf(path).model)
    m = pin.Model()        # kinds none of the URDFs has: spherical, unaligned prismatic, continuous about x
    j = m.addJoint(0, pin.JointModelSpherical(), pin.SE3(pin.exp3(np.array([0.1, 0.2, 0.3])), np.ones(3)), "s")
    j = m.addJoint(j, pin.JointModelPrismaticUnaligned(np.array([0.0, 0.6, 0.8])),
                   pin.SE3(np.eye(3), np.array([0.1, 0.0, 0.0])), "p")
    m.addJoint(j, pin.JointModelRUBX(), pin.SE3(pin.exp3(np.array([0.3, 0.0, 0.0])), np.zeros(3)), "c")
    models.append(m)
    mixed = tmp_path / "mixed.urdf"      # a continuous joint about an oblique axis (RevoluteUnboundedUnaligned)
    mixed.write_text('<robot name="m"><link name="a"/><link name="b"/><joint name="j" type="continuous">'
                     '<parent link="a"/><child link="b"/><origin xyz="0.1 0 0" rpy="0.3 0 0"/>'
                     '<axis xyz="0 0.6 0.8"/></joint></robot>')
    models.append(pin.buildModelFromUrdf(str(mixed)))
    return models


def test_tree_arrays_match_pinocchio(tmp_path):
    """Joint placements, world motion columns (Pinocchio's data.J) and integrate, to rounding."""
    rng = np.random.default_rng(2)
    for model in _models(tmp_path):
        data, tree = model.createData(), TreeArrays(model)
        q = np.array([pin.integrate(model, pin.neutral(model), rng.normal(0, 0.4, model.nv)) for _ in range(4)])
        v = rng.normal(0, 0.3, (4, model.nv))
        R, p = tree.placements(q)
        W = tree.motion_columns(R, p, np.arange(model.nv))
        moved = tree.integrate(q, v)
        for i in range(4):
            pin.computeJointJacobians(model, data, q[i])
            for jid in range(1, model.njoints):
                assert np.abs(data.oMi[jid].rotation - R[i, jid]).max() < 1e-14
                assert np.abs(data.oMi[jid].translation - p[i, jid]).max() < 1e-14
            assert np.abs(data.J.reshape(6, -1) - W[i]).max() < 1e-14     # eigenpy squeezes nv = 1
            reference = pin.integrate(model, q[i], v[i])
            pin.forwardKinematics(model, data, reference)
            expected = [data.oMi[jid].homogeneous.copy() for jid in range(1, model.njoints)]
            pin.forwardKinematics(model, data, moved[i])
            assert max(np.abs(data.oMi[jid].homogeneous - M).max()
                       for jid, M in zip(range(1, model.njoints), expected)) < 1e-14


@pytest.mark.parametrize("kind", ["point", "frame", "distance", "revolute"])
def test_closure_arrays_match_closure_rows(kind):
    rng = np.random.default_rng(4)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    closure = Closure("k", kind, "a", "b", {"point": 3, "frame": 6, "distance": 1, "revolute": 5}[kind], 0.4,
                      tuple(axis) if kind == "revolute" else None)
    M1 = [pin.exp6(rng.normal(0, 1, 6)) for _ in range(5)]
    M2 = [pin.exp6(rng.normal(0, 1, 6)) for _ in range(5)]
    c, D1, D2 = closure_arrays(kind, np.array([M.rotation for M in M1]), np.array([M.translation for M in M1]),
                               np.array([M.rotation for M in M2]), np.array([M.translation for M in M2]),
                               length=np.full(5, 0.4), axis=np.tile(axis, (5, 1)),
                               basis=np.tile(hinge_bases(axis[None]), (5, 1, 1)))
    for i in range(5):
        ck, d1, d2 = closure_rows(closure, M1[i], M2[i])
        assert max(np.abs(c[i] - ck).max(), np.abs(D1[i] - d1).max(), np.abs(D2[i] - d2).max()) < 1e-13


def _closure_jacobians(robot, n, seed):
    """c and C_s of the robot's closures at n random configurations (closed or not: the structure is the same)."""
    rng, model, loops = np.random.default_rng(seed), robot.model, robot.loops
    tree = TreeArrays(model)
    groups = closure_groups(model, loops, tree)
    q = np.array([pin.integrate(model, pin.neutral(model), rng.normal(0, 0.2, model.nv)) for _ in range(n)])
    st = closure_state(tree, groups, loops.n_rows, loops.solved_v, q)
    return groups, st["c"], st["Cs"]


def test_stewart_block_elimination_matches_dense_lu():
    """C_s of a 6-UPS eliminated leg by leg (PointArrow) against numpy's LU: the inverse, the Newton step and the
    damped step (C_s^T C_s + mu I)^-1 C_s^T c. Both are backward-stable eliminations, so they differ by
    ~eps cond(C_s) relative (cond for the normal matrix of the damped step: cond^2); 100 eps times that bounds it
    with room for the few hundred operations, and a wrong block or sign is O(1)."""
    robot = robocal.load_urdf(URDF / "stewart_6_6.urdf")
    groups, c, Cs = _closure_jacobians(robot, 20, seed=5)
    arrow = PointArrow.from_groups(groups, robot.loops.n_rows, len(robot.loops.solved_v))
    assert arrow is not None and arrow.own.shape == (6, 2) and len(arrow.shared) == 6
    cond = np.linalg.cond(Cs).max()
    eps = np.finfo(float).eps
    inverse = np.linalg.inv(Cs)
    assert _relative(arrow.inverse(Cs), inverse) < 100 * eps * cond
    newton = -np.linalg.solve(Cs, c[..., None])[..., 0]
    assert _relative(arrow.newton_step(Cs, c), newton) < 100 * eps * cond
    mu = np.einsum("ni,ni->n", c, c)
    normal = np.swapaxes(Cs, 1, 2) @ Cs + mu[:, None, None] * np.eye(Cs.shape[2])
    damped = -np.linalg.solve(normal, np.einsum("nmi,nm->ni", Cs, c)[..., None])[..., 0]
    assert _relative(arrow.damped_step(Cs, c, mu), damped) < 100 * eps * cond ** 2


def test_block_elimination_reports_breakdown_and_other_structures_stay_dense(tmp_path):
    """A leg whose two own columns are parallel (no normal: S has a zero row) or a platform coordinate that moves
    no closure makes the elimination raise (the caller then takes the dense LU and its singularity check); the
    linkage's revolute and distance closures have no such structure (None: dense path)."""
    robot = robocal.load_urdf(URDF / "stewart_6_6.urdf")
    groups, c, Cs = _closure_jacobians(robot, 3, seed=6)
    arrow = PointArrow.from_groups(groups, robot.loops.n_rows, len(robot.loops.solved_v))
    parallel = Cs.copy()
    parallel[0][np.ix_(arrow.rows[1], arrow.own[1])] = parallel[0][arrow.rows[1], arrow.own[1][0]][:, None]
    flat = Cs.copy()
    flat[:, :, arrow.shared[0]] = 0.0      # the platform's first coordinate moves no closure: S singular
    for broken in (parallel, flat):
        with np.errstate(divide="ignore", invalid="ignore"):
            with pytest.raises(np.linalg.LinAlgError):
                arrow.inverse(broken)
            with pytest.raises(np.linalg.LinAlgError):
                arrow.newton_step(broken, c)
    assert np.isfinite(arrow.inverse(Cs)).all()
    path = tmp_path / "linkage.urdf"
    path.write_text(LINKAGE)
    linkage = robocal.load_urdf(path)
    groups = closure_groups(linkage.model, linkage.loops, TreeArrays(linkage.model))
    assert PointArrow.from_groups(groups, linkage.loops.n_rows, len(linkage.loops.solved_v)) is None
