"""The batched Jacobian's GEMM run joint by joint (GemmBlocks) against the one dense product.

A joint's six twist-map rows reach only its own free columns (its placement, its offset, a calibrated
fixed link above it); the blocks are worked out from the layout, before any value is known, so they must
cover every entry the map can ever hold. Ties across joints share columns: then no blocks (dense GEMM).
"""
import numpy as np

from robocal import load_example
from robocal.design.simulate import perturb
from robocal.estimation.problem import Problem
from robocal.model import joint_jacobian_parts
from robocal.model.batch_kinematics import BatchKinematics, gemm_blocks
from robocal.model.joint_jacobian_parts import GemmBlocks
from robocal.model.parameters import robot_parameters
from robocal.residuals import PoseResidual


def _problem(rng, tie=None):
    robot = load_example("ur5")
    params = robot_parameters(robot, robot.joint_names, "full", frames={"tool0": True}, base=True)
    if tie:
        params.tie(*tie)
    params = perturb(params, rng)        # every placement away from zero: the twist map's blocks are dense
    values = rng.uniform(-2, 2, (30, 6))
    pose = PoseResidual("tracker", "tool0", np.arange(30), np.tile([0.4, 0.1, 0.5, 0, 0, 0, 1.0], (30, 1)))
    return Problem(robot, params, robot.joint_names, values, [pose])


def _blocks_and_map(problem):
    ms = problem.model_state()
    batch = BatchKinematics(ms, problem.sample_constants(ms), problem.values, None)
    jid = ms.kin_model.frames[ms.robot.frame_id("tool0")].parentJoint
    return gemm_blocks(ms.kin_model, ms, jid), batch.twist_map(ms)


def test_the_blocks_cover_every_entry_of_the_twist_map():
    problem = _problem(np.random.default_rng(1))
    blocks, tmap = _blocks_and_map(problem)
    assert blocks is not None and len(blocks.rows) == 6
    reached = np.zeros(tmap.shape, dtype=bool)
    for r, c in zip(blocks.rows, blocks.cols):
        reached[r, c] = True
    assert np.all(tmap[~reached] == 0.0)          # nothing outside the blocks
    assert np.all(np.any(tmap[:, blocks.uncovered] != 0.0, axis=0) == 0)
    names = problem.params.free_names
    assert {names[i].split(".")[0] for i in blocks.uncovered} == {"base", "tool0"}


def test_a_tie_across_joints_falls_back_to_the_dense_product():
    problem = _problem(np.random.default_rng(2), tie=("wrist_3_joint.offset", "wrist_2_joint.offset"))
    blocks, _ = _blocks_and_map(problem)
    assert blocks is None


def test_block_product_equals_the_dense_one_across_chunks(monkeypatch):
    rng = np.random.default_rng(3)
    rows, n_free = 50, 20
    cols = [slice(2, 5), np.array([6, 9, 10]), slice(12, 13)]
    tmap = np.zeros((18, n_free))
    for k, c in enumerate(cols):
        tmap[6 * k:6 * k + 6, c] = rng.normal(size=(6, len(np.arange(n_free)[c])))
    covered = np.concatenate([np.arange(n_free)[c] for c in cols])
    blocks = GemmBlocks([slice(6 * k, 6 * k + 6) for k in range(3)], cols, np.setdiff1d(np.arange(n_free), covered))
    folded = rng.normal(size=(rows, 18))
    monkeypatch.setattr(joint_jacobian_parts, "CHUNK_ROWS", 7)       # chunk edges inside the rows
    flat = np.full((rows, n_free), np.nan)                             # every entry must be written
    blocks.multiply(folded, tmap, flat)
    assert np.abs(flat - folded @ tmap).max() <= 1e-14 * np.abs(folded @ tmap).max()
