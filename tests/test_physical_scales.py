"""Issue 32, part 4: a physical scale for every robot kind (docs/validation.md gives the formulas), the loads they
rest on computed by hand here."""
import numpy as np
import pinocchio as pin
import pytest

from robocal import load_example
from robocal.estimation.physical_scale import (ANGLE_SCALE, LENGTH_FRACTION, JointLoads, compliance_reference,
                                               joint_loads, physical_scales)
from robocal.model.parameters import Parameter, robot_parameters
from validation_cases import JOINTS


class Problem:          # what physical_scales reads of a problem
    def __init__(self, robot, params, values):
        self.robot, self.params, self.joint_names, self.values, self.residuals = robot, params, JOINTS, values, []


def test_joint_loads_match_the_subtree_weight_computed_by_hand():
    robot = load_example("ur5")
    model = robot.model
    q = np.array([0.3, -1.1, 1.4, -0.5, 0.9, 0.2])
    loads = joint_loads(robot, JOINTS, q[None])
    data = model.createData()
    qfull = pin.neutral(model)
    for j, v in zip(JOINTS, q):
        qfull[model.joints[robot.joint_id(j)].idx_q] = v
    pin.forwardKinematics(model, data, qfull)
    g = model.gravity.linear
    for j in JOINTS:
        jid = robot.joint_id(j)
        origin = data.oMi[jid].translation
        beyond = [k for k in range(1, model.njoints) if jid in model.supports[k]]       # the joints it carries
        # the weight of every body beyond the joint, about its origin
        moment = sum(np.cross(data.oMi[k].act(model.inertias[k].lever) - origin, model.inertias[k].mass * g)
                     for k in beyond)
        axis = data.oMi[jid].rotation @ robot.joint_axis(jid)[0]
        # along: the gravity torque the joint's drive holds; across: what its bearing carries
        assert loads.along[j] == pytest.approx(abs(moment @ axis), abs=1e-9)
        assert loads.across[j] == pytest.approx(np.linalg.norm(moment - (moment @ axis) * axis), abs=1e-9)
    assert loads.effort == {j: e for j, e in zip(JOINTS, [150.0, 150.0, 150.0, 28.0, 28.0, 28.0])}


def test_compliance_scale_from_the_effort_limit_else_from_the_load_in_the_data():
    loads = JointLoads({"a": 5.0, "b": 5.0, "c": 5.0}, {}, {"a": 40.0, "b": 0.0, "c": 2.0})
    assert compliance_reference(loads, "a") == (40.0, "effort limit")
    assert compliance_reference(loads, "b") == (5.0, "largest gravity load in the data")   # no limit stated
    assert compliance_reference(loads, "c") == (5.0, "largest gravity load in the data")   # limit below the load


def test_every_robot_kind_has_its_scale():
    robot = load_example("ur5")
    params = robot_parameters(robot, JOINTS, "full", base=True, compliance=True, backlash=True, tilt=["elbow_joint"])
    params.add(Parameter("screw.lead", "transmission", "screw", 0, value=0.005, unit="m"))
    params.add(Parameter("screw.hand", "transmission", "screw", 0, value=1.0, vary=False))
    values = np.random.default_rng(0).uniform(-2, 2, (20, 6))
    scales = physical_scales(Problem(robot, params, values))
    loads = joint_loads(robot, JOINTS, values)
    size = scales.size
    assert scales.scale["elbow_joint.tx"] == pytest.approx(LENGTH_FRACTION * size)
    assert scales.scale["elbow_joint.offset"] == scales.scale["elbow_joint.rz"] == ANGLE_SCALE
    assert scales.scale["elbow_joint.backlash"] == ANGLE_SCALE / 2                       # the play 2|b| within it
    assert scales.scale["wrist_3_joint.compliance"] == pytest.approx(ANGLE_SCALE / 28.0)  # 10 mrad at 28 N m
    assert "effort limit" in scales.basis["wrist_3_joint.compliance"]
    assert scales.scale["elbow_joint.tilt"] == pytest.approx(ANGLE_SCALE / loads.across["elbow_joint"])
    assert scales.scale["screw.lead"] == pytest.approx(LENGTH_FRACTION * 0.005)        # 1 % of the lead
    assert "screw.hand" not in scales.scale and "base.tx" not in scales.scale          # discrete; registration
    # determined: 0.1 mm, 0.1 mrad, or the same deflection at the reference load
    assert scales.determined["elbow_joint.tx"] == 1e-4 and scales.determined["elbow_joint.backlash"] == 1e-4
    assert scales.determined["wrist_3_joint.compliance"] == pytest.approx(1e-4 / 28.0)
    assert scales.determined["screw.lead"] == pytest.approx(1e-4 * 0.005)
