"""A parallel-jaw gripper whose fingers ride four-bar linkages, built in Python as a Pinocchio model with constraint
models, and calibrated from a camera that sees both fingertips (docs/closed_loops.md, "Python").

Each finger is the coupler of a parallelogram four-bar: a driven crank and a passive rocker pivot on the palm
(0.02 m apart), both 0.06 m long, and the finger joins their ends, so it translates without turning. One motor
turns the right crank; a gear pair turns the left crank the other way (a robocal Coupling, ratio -1). The two
pins where the fingers meet the rockers are Pinocchio PointAnchorConstraintModels: 2 loops x 3 rows + 1 gear row
for 5 passive joints.

The true gripper differs from the drawing by up to 1 mm in the link lengths and fingertips, 10 mrad in
the motor's zero and 2 % in the gear ratio; the camera sees the tips with 20 um of noise. The fit recovers every
parameter within a few of its standard errors. Run:
    OMP_NUM_THREADS=1 python examples/closed_loops/gripper_four_bar.py
"""
import numpy as np
import pinocchio as pin

import robocal
from robocal.model import Coupling, Parameter, ParameterSet
from robocal.residuals import PointResidual

PIVOT, LINK, SAMPLES, NOISE = 0.02, 0.06, 40, 2e-5


def build_gripper():
    """(model, constraint models): the palm's tree (the fingers hang on their cranks) and the two rocker pins."""
    model = pin.Model()
    model.name = "gripper"
    constraints = []
    for side, sign in (("r", 1.0), ("l", -1.0)):
        x = sign * np.array([0.01, 0.0, 0.0])
        crank = model.addJoint(0, pin.JointModelRZ(), pin.SE3(np.eye(3), x), f"{side}_crank")
        finger = model.addJoint(crank, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array([0.0, LINK, 0.0])),
                                f"{side}_finger")
        rocker = model.addJoint(0, pin.JointModelRZ(), pin.SE3(np.eye(3), x + sign * np.array([PIVOT, 0.0, 0.0])),
                                f"{side}_rocker")
        model.addFrame(pin.Frame(f"{side}_tip", finger, pin.SE3(np.eye(3), np.array([sign * 0.01, 0.04, 0.0])),
                                 pin.FrameType.OP_FRAME))
        pinned = pin.PointAnchorConstraintModel(model, finger, pin.SE3(np.eye(3), np.array([sign * PIVOT, 0.0, 0.0])),
                                                rocker, pin.SE3(np.eye(3), np.array([0.0, LINK, 0.0])))
        pinned.name = f"{side}_pin"
        constraints.append(pinned)
    return model, constraints


def gripper_parameters() -> ParameterSet:
    """What the calibration fits: the motor's zero, the gear ratio, the left crank's zero, the cranks' and rockers'
    lengths and the fingertips (in the plane; the palm, its pivots machined, is the camera's frame)."""
    params = ParameterSet([Parameter("r_crank.offset", "joint_offset", "r_crank", unit="rad"),
                           Parameter("gear.ratio", "transmission", "gear", value=-1.0)])
    components = ("tx", "ty", "tz", "rx", "ry", "rz")
    for name, kind, chosen in (("l_crank", "joint_placement", ("rz",)), ("r_finger", "joint_placement", ("ty",)),
                               ("l_finger", "joint_placement", ("ty",)), ("r_pin.link2", "frame_placement", ("ty",)),
                               ("l_pin.link2", "frame_placement", ("ty",)), ("r_tip", "frame_placement", ("tx", "ty")),
                               ("l_tip", "frame_placement", ("tx", "ty"))):
        for c in chosen:
            params.add(Parameter(f"{name}.{c}", kind, name, components.index(c), unit="rad" if c[0] == "r" else "m"))
    return params


def main(samples: int = SAMPLES, seed: int = 3):
    model, constraints = build_gripper()
    robot = robocal.robot_from_pinocchio(model, constraints, actuated=["r_crank"],
                                         relations=[Coupling("gear", "r_crank", "l_crank", -1.0)])
    rng = np.random.default_rng(seed)
    motor = rng.uniform(-0.6, 0.6, (samples, 1))            # the fingers open and close by +-3.4 cm
    tips = [PointResidual(f"{side}_camera", f"{side}_tip", np.arange(samples), np.zeros((samples, 3)),
                          sigma=NOISE) for side in "rl"]
    problem = robocal.Problem(robot, gripper_parameters(), ["r_crank"], motor, tips)
    truth = problem.params.copy()          # with the cameras' (fixed) tip points the residuals added
    for p in truth:
        if p.kind != "auxiliary":
            p.value += rng.uniform(-1, 1) * {"m": 1e-3, "rad": 1e-2}.get(p.unit, 0.02)
    robocal.simulate_measurements(problem, truth, rng)
    result = robocal.calibrate(problem)
    print(result.summary())
    print(f"\n{'parameter':<18}{'truth':>12}{'estimate':>12}{'stderr':>10}{'|error| / stderr':>18}")
    worst = 0.0
    for p in result.params:
        if p.kind == "auxiliary":
            continue
        t = truth[p.name].value
        worst = max(worst, abs(p.value - t) / p.stderr)
        print(f"{p.name:<18}{t:>12.6f}{p.value:>12.6f}{p.stderr:>10.2g}{abs(p.value - t) / p.stderr:>18.2f}")
    return result, worst


if __name__ == "__main__":
    main()
