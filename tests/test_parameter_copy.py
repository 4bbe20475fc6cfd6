"""ParameterSet.copy: an independent copy equal to copy.deepcopy's, for every kind of parameter a robot has."""
import copy

import robocal
from robocal.model.parameters import robot_parameters


def test_a_copy_equals_deepcopy_and_shares_nothing_mutable():
    robot = robocal.load_example("ur5")
    joints = list(robot.model.names[1:])
    params = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True, compliance=True)
    first = next(iter(params))
    first.tied_to, first.confounded_with = {"a": 0.5}, [("b", 0.9)]
    first.value, first.stderr, first.prior_sigma = 0.01, 1e-4, 2e-3
    copied, deep = params.copy(), [copy.deepcopy(p) for p in params]
    assert [p.__dict__ for p in copied] == [p.__dict__ for p in deep]
    twin = next(iter(copied))
    twin.tied_to["a"], twin.confounded_with[0], twin.value = 7.0, ("c", 0.1), 3.0
    assert first.tied_to == {"a": 0.5} and first.confounded_with == [("b", 0.9)] and first.value == 0.01
    assert params.values() == {p.name: p.value for p in deep}
