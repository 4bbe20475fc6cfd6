"""The batched closed-chain pass through its numba kernels (robocal.model.closed_chain_compiled) against its numpy
path and the per-sample reference: same residuals and Jacobians, same fallbacks and errors.

Both batched paths do the same arithmetic in another order, so they differ by rounding: 1e-10 relative (the
issue's bound, as tests/test_closed_chain_batch.py) sits far above the ~1e-14 they show and far below any wrong
term (a missing or mis-signed row is O(1) of the Jacobian's scale).
"""
import numpy as np
import pinocchio as pin
import pytest

from reference_evaluation import reference_evaluate
import robocal
from robocal.errors import AssemblyError
from robocal.estimation.calibrate import calibrate
from robocal.model.closed_chain_batch import ClosedChainBatch
from robocal.model import closed_chain_compiled
from robocal.model.closed_chain_compiled import CompiledPass, numba_wanted
from robocal.model.closure_groups import closure_groups, closure_state
from robocal.model.point_closure_solve import PointArrow
from robocal.estimation.problem import Problem
from robocal.model.tree_arrays import TreeArrays
from robocal.systems.stewart import calibration as sc, modes as sm
from test_closed_chain_batch import URDF, _models, linkage_problem, stewart_problem

pytest.importorskip("numba")
RTOL = 1e-10


@pytest.fixture(autouse=True)
def kernels_for_small_passes(monkeypatch):
    """These problems have a few samples: the kernels by default on them too (NUMBA_MIN_SAMPLES is a cost rule)."""
    monkeypatch.setattr(closed_chain_compiled, "NUMBA_MIN_SAMPLES", 0)


def _relative(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


def _three_paths(make, monkeypatch):
    """numba, numpy and per-sample evaluations, each on its own problem: a first pass from the neutral
    configuration, then one from its solutions after a parameter step (the predicted starts)."""
    problems = {"numba": make(), "numpy": make(), "reference": make()}
    step = np.random.default_rng(9).normal(0, 1e-4, len(problems["numba"].params.free_names))
    for k in range(2):
        out = {}
        for name, problem in problems.items():
            if k:
                problem.params.set_free_values(problem.params.free_values() + step)
            if name == "numpy":
                monkeypatch.setenv("ROBOCAL_NO_NUMBA", "1")
            else:
                monkeypatch.delenv("ROBOCAL_NO_NUMBA", raising=False)
            out[name] = reference_evaluate(problem) if name == "reference" else problem.evaluate()
        for other in ("numpy", "reference"):
            assert _relative(out["numba"].r, out[other].r) < RTOL
            assert _relative(out["numba"].J, out[other].J) < RTOL
        assert np.abs(out["numba"].J).max() > 1.0     # the comparison is not between zeros
    return problems


def _batch(problem, use_numba):
    ms = problem.model_state()
    return ClosedChainBatch(ms, problem.values, {}, True, None, {}, use_numba=use_numba)


def test_stewart_numba_path_matches_numpy_and_per_sample(monkeypatch):
    problems = _three_paths(stewart_problem, monkeypatch)
    batch = _batch(problems["numba"], True)
    assert batch.compiled is not None and batch.arrow is not None      # the kernels and the arrow did the work
    assert _batch(problems["numba"], False).compiled is None


def test_four_bar_numba_path_matches_numpy_and_per_sample(tmp_path, monkeypatch):
    """The crank-rocker four-bar closed by a revolute closure, plus a distance closure: the tree kernels with the
    numpy rows of those kinds, the dense LU (no arrow), more rows than unknowns."""
    problems = _three_paths(lambda: linkage_problem(tmp_path), monkeypatch)
    batch = _batch(problems["numba"], True)
    assert batch.compiled is not None and batch.arrow is None


def test_tree_kernels_match_tree_arrays(tmp_path):
    """Placements, motion columns and integrate on every joint kind the batched path accepts (free-flyer,
    spherical, unaligned prismatic, continuous about x and an oblique axis), to rounding."""
    rng = np.random.default_rng(3)
    for model in _models(tmp_path):
        tree = TreeArrays(model)
        q = np.array([pin.integrate(model, pin.neutral(model), rng.normal(0, 0.4, model.nv)) for _ in range(5)])
        v = rng.normal(0, 0.3, (5, model.nv))
        v[0] *= 1e-6        # the exp maps' small-angle branches
        compiled = CompiledPass(tree, [], 0, np.arange(model.nv), _NoTwists(), [], [], np.zeros((0, 0), int), 0,
                                None)
        st = compiled.state(q)
        R, p = tree.placements(q)
        assert np.abs(st["R"] - R).max() < 1e-14 and np.abs(st["p"] - p).max() < 1e-14
        assert np.abs(st["W"] - tree.motion_columns(R, p, np.arange(model.nv))).max() < 1e-14
        assert np.abs(compiled.integrate(q, v) - tree.integrate(q, v)).max() < 1e-14


class _NoTwists:
    """TreeTwists of a model without free parameters."""
    active = placed = offset_v = np.zeros(0, dtype=int)
    blocks = np.zeros((0, 6, 0))
    offset_rows, offset_owner = [], []


def test_arrow_kernels_break_down_to_nan_and_the_pass_takes_the_dense_path():
    """A leg whose two own columns are parallel, or a platform coordinate that moves no closure: the kernels leave
    NaN where numpy's elimination raises, and the pass's step, inverse and singularity check are then the numpy
    path's (the dense LU, the same AssemblyError)."""
    problem = stewart_problem(n=3)
    numba_batch, numpy_batch = _batch(problem, True), _batch(problem, False)
    robot = problem.robot
    tree = TreeArrays(robot.model)
    groups = closure_groups(robot.model, robot.loops, tree)
    arrow = PointArrow.from_groups(groups, robot.loops.n_rows, len(robot.loops.solved_v))
    rng = np.random.default_rng(6)
    q = np.array([pin.integrate(robot.model, pin.neutral(robot.model), rng.normal(0, 0.2, robot.model.nv))
                  for _ in range(3)])
    st = closure_state(tree, groups, robot.loops.n_rows, robot.loops.solved_v, q)
    c, Cs = st["c"], st["Cs"]
    parallel = Cs.copy()
    parallel[0][np.ix_(arrow.rows[1], arrow.own[1])] = parallel[0][arrow.rows[1], arrow.own[1][0]][:, None]
    flat = Cs.copy()
    flat[:, :, arrow.shared[0]] = 0.0
    plain = np.full(3, 1e-30)      # below NEGLIGIBLE_DAMPING: the Newton step

    def step(batch, broken):
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            try:
                return batch._step(broken, c, plain)
            except np.linalg.LinAlgError:
                return "singular"

    for broken in (parallel, flat):
        assert np.isnan(numba_batch.compiled.newton_step(broken, c)[0]).all()
        assert np.isnan(numba_batch.compiled.inverse(broken)[0][0]).all()
        a, b = step(numba_batch, broken), step(numpy_batch, broken)    # both from the same dense solve
        assert (a == b if isinstance(a, str) else np.array_equal(a, b, equal_nan=True))
        mu = np.full(3, 1e-3)        # the damped step stays regular: kernel against numpy's elimination
        assert _relative(numba_batch._step(broken, c, mu), numpy_batch._step(broken, c, mu)) < RTOL
    labels = np.array([7, 8, 9])
    messages = []
    for batch in (numba_batch, numpy_batch):
        with pytest.raises(AssemblyError, match="sample 7") as error:
            batch._solver(flat, labels)
        messages.append(str(error.value))
    assert messages[0] == messages[1]
    assert np.abs(numba_batch._solver(Cs, labels) - numpy_batch._solver(Cs, labels)).max() < 1e-10 * np.abs(
        numpy_batch._solver(Cs, labels)).max()


def test_unreachable_sample_raises_the_same_error_on_both_paths(monkeypatch):
    messages = []
    for flag in ("0", "1"):
        monkeypatch.setenv("ROBOCAL_NO_NUMBA", flag)
        problem = stewart_problem(n=4)
        problem.values[2, 0] += 2.0        # one strut 2 m longer than the others: no assembly
        with pytest.raises(AssemblyError, match="sample 2") as error:
            problem.evaluate()
        messages.append(str(error.value))
    assert messages[0] == messages[1]



def test_parameter_rows_kernel_matches_numpy(tmp_path):
    """C_theta of the kernels (kept at its possibly-nonzero entries) equals the numpy rows on the Stewart (point
    closures: every parameter kind the closures see) and on the linkage (revolute and distance rows: numpy
    inside the compiled pass)."""
    for problem in (stewart_problem(n=6), linkage_problem(tmp_path, n=6)):
        problem.evaluate()          # closed warm starts
        numba_batch, numpy_batch = _batch(problem, True), _batch(problem, False)
        q = numpy_batch.q
        compiled = numba_batch.compiled.dense_parameter_rows(numba_batch._parameter_rows(numba_batch._state(q)))
        reference = numpy_batch._parameter_rows(numpy_batch._state(q))
        assert np.abs(reference).max() > 0.1 and _relative(compiled, reference) < RTOL


def test_numba_is_chosen_by_the_pass_size_alone_and_switched_off_by_the_environment(monkeypatch):
    """By the pass's size, not by what the process ran before (the kernels are loaded by now): a fit gives the same
    numbers serially and on fresh workers."""
    monkeypatch.setattr(closed_chain_compiled, "NUMBA_MIN_SAMPLES", 1000)
    assert numba_wanted(None, 1000) and numba_wanted(True, 3) and not numba_wanted(False, 5000)
    assert not numba_wanted(None, 999)
    monkeypatch.setenv("ROBOCAL_NO_NUMBA", "1")
    assert not numba_wanted(None, 5000)


def _stewart_fit(n, seed=0):
    """The 42-parameter pose fit of benchmarks/closed_chain.py (anchors and strut offsets, true machine N(0, 1 mm),
    noise-free poses)."""
    rng = np.random.default_rng(seed)
    robot = robocal.load_urdf(URDF / "stewart_6_6.urdf")
    truth = sc.stewart_parameters()
    for p in truth:
        p.value = rng.normal(0.0, 1e-3)
    tool = sm.Tool(0.2, 0.003)
    tips = sc.random_tips(n, rng)
    abc, R = sc.random_orientations(n, rng)
    struts = sc.struts(sc.geometry(robot, truth), sc.tip_to_platform(tips, R, tool))
    return Problem(robot, sc.stewart_parameters(), sc.actuated(robot), struts,
                   sm.pose_residuals("pose", robot, np.arange(n), np.column_stack([tips, abc]), [1] * 6, tool,
                                     (1e-6, 1e-6)))


def test_calibration_gives_the_same_parameters_on_both_paths(monkeypatch):
    """A whole fit (every pass, the predicted starts included) through the kernels and through numpy: the
    parameters agree to 1e-10 (both paths' differences are rounding, ~1e-15 per pass)."""
    fitted = []
    for flag in ("0", "1"):
        monkeypatch.setenv("ROBOCAL_NO_NUMBA", flag)
        problem = _stewart_fit(30)
        calibrate(problem)
        fitted.append(problem.params.free_values())
    assert np.abs(fitted[0]).max() > 1e-4 and np.abs(fitted[0] - fitted[1]).max() < 1e-10


def test_point_and_distance_closures_together_match_numpy_and_per_sample(tmp_path, monkeypatch):
    """The linkage with its hinge as a spherical (point) closure: point rows in the kernels and the distance
    closure's rows in numpy in one pass, one C_theta pattern over both (no arrow: more rows than unknowns)."""
    import test_closed_chain_batch
    mixed = test_closed_chain_batch.LINKAGE.replace('<loop_joint name="hinge" type="revolute"><axis xyz="0 0 1"/>',
                                                    '<loop_joint name="hinge" type="spherical">')
    assert mixed != test_closed_chain_batch.LINKAGE
    monkeypatch.setattr(test_closed_chain_batch, "LINKAGE", mixed)
    problems = _three_paths(lambda: linkage_problem(tmp_path), monkeypatch)
    batch = _batch(problems["numba"], True)
    assert sorted(g.kind for g in batch.groups) == ["distance", "point"] and batch.compiled is not None
