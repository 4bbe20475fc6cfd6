"""The pruned pose search (bounds, block updates) chooses exactly the poses of a plain search that evaluates
every candidate's criterion from its own information matrix (tests/reference_pose_selection.py)."""
import numpy as np
import pytest

from robocal.design.candidates import random_candidates
from robocal.design import criteria
from robocal.design.criteria import CRITERIA
from robocal.design.prediction import pose_jacobians, position_weight
from robocal.design.selection import DesignMatrix, select_poses
from reference_pose_selection import reference_select
from synthetic_cases import ur5_pose_problem


@pytest.fixture(scope="module")
def ur5_design():
    rng = np.random.default_rng(5)
    problem = ur5_pose_problem(rng, 50)
    problem.values = random_candidates(problem.robot, problem.joint_names, 50, rng)
    validation = random_candidates(problem.robot, problem.joint_names, 40, rng)
    return DesignMatrix.from_problem(problem), position_weight(pose_jacobians(problem, "tool0", validation))


@pytest.mark.parametrize("chunk", [4, criteria.CHUNK])
@pytest.mark.parametrize("criterion", CRITERIA)
def test_same_poses_as_the_plain_search(ur5_design, criterion, chunk, monkeypatch):
    # chunks of 4 of the ~45 outside candidates make the bounds prune here as they do on 1000 candidates
    # (bounds lowered by 10 % then choose other poses for E, O2 and O5: the comparison can fail)
    monkeypatch.setattr(criteria, "CHUNK", chunk)
    design, W = ur5_design
    sel = select_poses(design, 8, criterion, W=W)
    assert sel.exchanges > 0                       # the exchange step is exercised, not only the greedy start
    np.testing.assert_array_equal(sel.chosen, reference_select(design, 8, criterion, W=W))
