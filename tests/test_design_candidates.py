"""Candidate generation: limits, grids, measurement volumes and the exclusion of near-singular poses."""
import numpy as np
import pytest

from robocal import load_example
from robocal.design.candidates import (MeasurementVolume, filter_candidates, grid_candidates,
                                       random_candidates)
from robocal.errors import InputError
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters


@pytest.fixture(scope="module")
def ur5():
    robot = load_example("ur5")
    joints = robot.joint_names
    return robot, joints, ModelState(robot, robot_parameters(robot, joints, "offsets"), joints)


def test_random_candidates_stay_inside_the_shrunk_limits(ur5):
    robot, joints, _ = ur5
    q = random_candidates(robot, joints, 500, np.random.default_rng(0), margin=0.1)
    lo, hi = robot.limits(joints)
    mid, half = (lo + hi) / 2, (hi - lo) / 2 * 0.9
    assert q.shape == (500, 6) and np.all(q >= mid - half) and np.all(q <= mid + half)
    np.testing.assert_array_equal(q, random_candidates(robot, joints, 500, np.random.default_rng(0), margin=0.1))


def test_grid_has_every_combination(ur5):
    robot, joints, _ = ur5
    q = grid_candidates(robot, joints, [3, 2, 1, 1, 1, 2])
    assert q.shape == (12, 6)
    assert len({tuple(r) for r in q}) == 12
    lo, hi = robot.limits(joints)
    np.testing.assert_allclose(q[:, 2], (lo[2] + hi[2]) / 2)    # one level: the middle of the range
    with pytest.raises(InputError, match="levels"):
        grid_candidates(robot, joints, 0)


def test_volume_box_and_range_shell():
    vol = MeasurementVolume.from_dict({"box": {"min": [-1, -1, 0], "max": [1, 1, 2]},
                                       "sphere": {"center": [0, 0, 0], "max_range": 1.5, "min_range": 0.2}})
    pts = np.array([[0.5, 0.5, 0.5], [0.1, 0.0, 0.0], [0.9, 0.9, 1.0], [0.5, 0.0, -0.1]])
    np.testing.assert_array_equal(vol.contains(pts), [True, False, False, False])
    assert MeasurementVolume.from_dict(None) is None


@pytest.mark.parametrize("bad, field", [({"cube": {}}, "plan.volume.cube"),
                                        ({"box": {"min": [0, 0], "max": [1, 1, 1]}}, "plan.volume.box.min"),
                                        ({"box": {"min": [0, 0, 2], "max": [1, 1, 1]}}, "plan.volume.box"),
                                        ({"sphere": {"center": [0, 0, 0], "max_range": -1}}, "plan.volume.sphere")])
def test_bad_volume_names_the_field(bad, field):
    with pytest.raises(InputError) as err:
        MeasurementVolume.from_dict(bad, source="plan.yaml")
    assert err.value.field == field and err.value.source == "plan.yaml"


def test_filter_drops_wrist_singularities_and_poses_outside_the_volume(ur5):
    robot, joints, ms = ur5
    q = random_candidates(robot, joints, 40, np.random.default_rng(1))
    q[:5, 4] = 0.0                        # wrist_2 at 0: wrist singularity (joints 4 and 6 aligned)
    keep_all = filter_candidates(ms, q, "tool0")
    assert keep_all.dropped["near singular"] >= 5 and not set(range(5)) & set(keep_all.kept)
    assert np.all(keep_all.dexterity[:5] < 1e-9)
    # A box that holds only the positive-x half of the workspace
    x = np.array([ms.sample(v).pose("tool0").translation[0] for v in q])
    vol = MeasurementVolume(box=(np.array([0.0, -5, -5]), np.array([5.0, 5, 5])))
    f = filter_candidates(ms, q, "tool0", volume=vol)
    np.testing.assert_array_equal(f.kept, [i for i in keep_all.kept if x[i] >= 0])
    assert f.dropped["outside volume"] == sum(1 for i in keep_all.kept if x[i] < 0)
