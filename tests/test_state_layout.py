"""The value-independent part of ModelState is worked out once per parameter structure and reused:
a change of values reuses it, a change of structure (a parameter fixed, a tie) gets a new one, and a
ModelState built on a reused layout equals one built on a robot that never cached anything."""
import numpy as np
import pinocchio as pin
import pytest

from robocal import load_example
from robocal.model.kinematics import ModelState
from robocal.model.parameters import robot_parameters
from robocal.model.state_layout import state_layout


def ur5_case():
    robot = load_example("ur5")
    joints = robot.joint_names
    params = robot_parameters(robot, joints, "full", frames={"tool0": True}, base=True)
    rng = np.random.default_rng(3)
    for p in params:
        p.value = rng.normal(0.0, 1e-2)
    return robot, joints, params


def state_arrays(ms: ModelState) -> list[np.ndarray]:
    placements = [ms.model.jointPlacements[j].homogeneous for j in range(1, ms.model.njoints)]
    frames = [f.placement.homogeneous for f in ms.model.frames]
    return [ms.P_joint, ms.P_offset, ms.P_base, ms.offsets, ms.base.homogeneous, *placements, *frames,
            *[ms.P_frame[k] for k in sorted(ms.P_frame)]]


def assert_same_state(a: ModelState, b: ModelState) -> None:
    assert a.n_free == b.n_free and sorted(a.P_frame) == sorted(b.P_frame)
    for x, y in zip(state_arrays(a), state_arrays(b)):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-15)


def test_values_reuse_the_layout_and_structure_changes_replace_it():
    robot, joints, params = ur5_case()
    first = state_layout(robot, params, joints)
    params["elbow_joint.rx"].value += 0.3
    assert state_layout(robot, params, joints) is first
    params["elbow_joint.tx"].vary = False
    fixed = state_layout(robot, params, joints)
    assert fixed is not first and fixed.n_free == first.n_free - 1
    params.tie("wrist_1_joint.ty", "elbow_joint.ty")
    tied = state_layout(robot, params, joints)
    assert tied is not fixed and tied.n_free == fixed.n_free - 1
    params["elbow_joint.tx"].vary = True
    params["wrist_1_joint.ty"].tied_to = None
    assert state_layout(robot, params, joints) is first       # the first structure again


@pytest.mark.parametrize("change", ["values", "fixed", "tied"])
def test_a_state_on_a_reused_layout_equals_one_built_from_scratch(change):
    robot, joints, params = ur5_case()
    ModelState(robot, params, joints)                          # fills the robot's layout cache
    if change == "values":
        params["shoulder_lift_joint.rz"].value = 0.2
        params["tool0.tx"].value = -0.05
    elif change == "fixed":
        params["shoulder_lift_joint.offset"].vary = False
    else:
        params.tie("wrist_2_joint.tx", {"elbow_joint.tx": 0.5})
    reused = ModelState(robot, params, joints)
    fresh_robot = load_example("ur5")
    assert "_state_layouts" not in fresh_robot.__dict__
    assert_same_state(reused, ModelState(fresh_robot, params, joints))


def test_a_tied_follower_moves_its_joint_and_counts_in_its_leaders_column():
    robot, joints, params = ur5_case()
    params.tie("wrist_2_joint.tx", {"elbow_joint.tx": 0.5})
    ms = ModelState(robot, params, joints)
    jid = robot.joint_id("wrist_2_joint")
    nominal = robot.model.jointPlacements[jid]
    delta = np.array([params[f"wrist_2_joint.{c}"].value for c in ("tx", "ty", "tz", "rx", "ry", "rz")])
    np.testing.assert_allclose(ms.model.jointPlacements[jid].homogeneous,
                               (nominal * pin.exp6(pin.Motion(delta))).homogeneous, atol=1e-15)
    leader = params.free_names.index("elbow_joint.tx")
    expected = 0.5 * pin.Jexp6(pin.Motion(delta))[:, 0]
    np.testing.assert_allclose(ms.P_joint[6 * (jid - 1):6 * jid, leader], expected, atol=1e-15)
