"""Closed chains from MJCF (robocal.model.mjcf): the loops of `<equality>`, the same machine as its URDF, and bad
files named by file, line and constraint."""
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import robocal
from robocal.errors import InputError
from robocal.estimation.calibrate import calibrate
from robocal.estimation.problem import Problem
from robocal.model.loops import assemble
from robocal.model.mjcf import load_mjcf
from robocal.systems.stewart import calibration as sc, modes as sm

ROOT = Path(__file__).resolve().parents[1]
STEWART_URDF = ROOT / "urdf" / "stewart_6_6.urdf"
STEWART_MJCF = ROOT / "examples" / "closed_loops" / "stewart_6_6.xml"
FOURBAR_MJCF = ROOT / "examples" / "closed_loops" / "fourbar.xml"

# a planar four-bar (ground 0.3, crank 0.1, coupler 0.3, rocker 0.1 m) drawn in its closed collinear pose
TREE = """<worldbody><body name="ground">
  <body name="crank_link"><joint name="crank" type="hinge" axis="0 0 1"/>
    <body name="coupler_link" pos="0.1 0 0"><joint name="coupler_joint" type="hinge" axis="0 0 1"/>
      <site name="coupler_end" pos="0.3 0 0"/></body></body>
  <body name="rocker_link" pos="0.3 0 0"><joint name="rocker" type="hinge" axis="0 0 1"/>
    <site name="rocker_end" pos="0.1 0 0"/></body>
</body></worldbody>"""


def write(tmp_path, body: str, name: str = "machine.xml") -> Path:
    path = tmp_path / name
    path.write_text(f'<mujoco model="m">\n<compiler angle="radian"/>\n{body}\n</mujoco>\n')
    return path


def test_connect_weld_and_joint_equalities_become_loops(tmp_path):
    path = write(tmp_path, TREE + """
<equality>
  <connect name="pin" body1="coupler_link" body2="rocker_link" anchor="0.3 0 0"/>
  <connect site1="coupler_end" site2="rocker_end"/>
  <weld body1="coupler_link" body2="rocker_link"/>
  <joint name="mirror" joint1="rocker" joint2="crank" polycoef="0 1 0 0 0"/>
</equality>
<actuator><motor joint="crank"/></actuator>""")
    robot = load_mjcf(path)
    loops = robot.loops
    assert [(c.name, c.kind) for c in loops.closures] == [("pin", "point"), ("connect2", "point"), ("weld1", "frame")]
    assert loops.actuated == ["crank"]
    (coupling,) = loops.couplings
    assert (coupling.name, coupling.successor_joint, coupling.predecessor_joint, coupling.ratio) == \
        ("mirror", "rocker", "crank", 1.0)
    # the body form's second anchor comes from the drawn pose: rocker end, 0.1 m along the rocker
    f2 = robot.model.frames[robot.frame_id("pin.link2")]
    assert robot.model.names[f2.parentJoint] == "rocker"
    np.testing.assert_allclose(f2.placement.homogeneous, pin.SE3(np.eye(3), np.array([0.1, 0, 0])).homogeneous,
                               atol=1e-15)
    assert robot.source == str(path)


def rocker_tip(crank: float) -> np.ndarray:
    """Closed form of the example's open crank-rocker branch: the coupler/rocker pin in the plane, from the crank
    angle (ground 0.3, crank 0.1, coupler 0.28, rocker 0.22 m; the crank drawn at 90 deg is its joint zero)."""
    a = 0.1 * np.array([np.cos(np.pi / 2 + crank), np.sin(np.pi / 2 + crank)])
    pivot = np.array([0.3, 0.0])
    d = np.linalg.norm(pivot - a)
    ex = (pivot - a) / d
    x = (0.28 ** 2 - 0.22 ** 2 + d * d) / (2 * d)
    return a + x * ex + np.sqrt(0.28 ** 2 - x * x) * np.array([-ex[1], ex[0]])


def test_fourbar_mjcf_assembles_as_its_closed_form():
    robot = load_mjcf(FOURBAR_MJCF)
    assert robot.loops.actuated == ["crank"] and [c.name for c in robot.loops.closures] == ["pin"]
    data = robot.model.createData()
    q = robot.neutral()
    for crank in np.linspace(-1.0, 1.0, 9):          # warm-started sweep: the drawn (open) branch throughout
        q = assemble(robot, robot.model, [crank], q_guess=q)
        pin.framesForwardKinematics(robot.model, data, q)
        for frame in ("pin.link1", "pin.link2"):
            np.testing.assert_allclose(data.oMf[robot.frame_id(frame)].translation[:2], rocker_tip(crank), atol=1e-12)


def test_stewart_mjcf_is_the_urdf_machine():
    urdf, mjcf = robocal.load_urdf(STEWART_URDF), load_mjcf(STEWART_MJCF)
    assert list(mjcf.model.names) == list(urdf.model.names)       # same joints, same order
    for j in range(1, urdf.model.njoints):
        np.testing.assert_allclose(mjcf.model.jointPlacements[j].homogeneous, urdf.model.jointPlacements[j].homogeneous,
                                   atol=1e-14)     # quaternion vs rpy text: rounding only
    assert mjcf.loops.actuated == urdf.loops.actuated and mjcf.loops.passive == urdf.loops.passive
    for name in [c.frame1 for c in urdf.loops.closures] + [c.frame2 for c in urdf.loops.closures] + ["tool"]:
        a, b = mjcf.model.frames[mjcf.frame_id(name)], urdf.model.frames[urdf.frame_id(name)]
        assert mjcf.model.names[a.parentJoint] == urdf.model.names[b.parentJoint]
        np.testing.assert_allclose(a.placement.homogeneous, b.placement.homogeneous, atol=1e-15)


def stewart_fit(robot, n: int = 40):
    """The 42-parameter pose calibration of benchmarks/closed_chain.py on one robot: true machine N(0, 1 mm), poses
    measured with N(0, 10 um) / N(0, 10 urad) noise (so the fit does not end on an exact zero)."""
    rng = np.random.default_rng(11)
    tool = sm.Tool(0.2, 0.003)
    truth = sc.stewart_parameters()
    for p in truth:
        p.value = rng.normal(0.0, 1e-3)
    tips = sc.random_tips(n, rng)
    abc, R = sc.random_orientations(n, rng)
    struts = sc.struts(sc.geometry(robot, truth), sc.tip_to_platform(tips, R, tool))
    rows = np.column_stack([tips + rng.normal(0, 1e-5, tips.shape), abc + rng.normal(0, 1e-5, abc.shape)])
    problem = Problem(robot, sc.stewart_parameters(), sc.actuated(robot), struts,
                      sm.pose_residuals("pose", robot, np.arange(n), rows, [1] * 6, tool, (1e-5, 1e-5)))
    result = calibrate(problem)
    return result, {p.name: p.value for p in truth}


def test_mjcf_and_urdf_stewart_give_the_same_calibration():
    """Same machine, same data: the fits agree to 1e-9 m (they differ by the 1e-15 placement rounding above and the
    solver's rounding); each parameter is within 5 of its standard errors (from the 10 um / 10 urad noise) of the
    truth."""
    r_urdf, truth = stewart_fit(robocal.load_urdf(STEWART_URDF))
    r_mjcf, _ = stewart_fit(load_mjcf(STEWART_MJCF))
    assert r_urdf.success and r_mjcf.success
    a, b = r_urdf.params.values(), r_mjcf.params.values()
    assert a.keys() == b.keys() and len(a) == 42
    worst = max(abs(a[k] - b[k]) for k in a)
    assert worst < 1e-9, worst
    for p in r_mjcf.params:
        assert abs(p.value - truth[p.name]) < 5 * p.stderr, (p.name, p.value - truth[p.name], p.stderr)


@pytest.mark.parametrize("equality, field, message", [
    ('<connect name="pin" body1="coupler_link" body2="nope" anchor="0.3 0 0"/>', "body2",
     "equality constraint 'pin' (<connect>) names body 'nope' in body2, which is not in the model"),
    ('<weld body1="ghost" body2="rocker_link"/>', "body1",
     "equality constraint 'weld1' (<weld>) names body 'ghost' in body1"),
    ('<connect name="s" site1="coupler_end" site2="elsewhere"/>', "site2", "names site 'elsewhere' in site2"),
    ('<joint name="gear" joint1="rocker" joint2="wrist"/>', "joint2",
     "equality constraint 'gear' (<joint>) names joint 'wrist' in joint2, which is not in the model"),
    ('<joint name="cubic" joint1="rocker" joint2="crank" polycoef="0 1 0 0.2 0"/>', "polycoef",
     "joint equality 'cubic': robocal reads joint1 = ratio * joint2"),
    ('<tendon name="t" tendon1="x"/>', "t", "equality constraint 't' is a <tendon>"),
    ('<connect name="off" active="false" body1="coupler_link" body2="rocker_link" anchor="0.3 0 0"/>', "off",
     "'off' is inactive"),
])
def test_bad_equalities_are_named_by_file_line_and_constraint(tmp_path, equality, field, message):
    path = write(tmp_path, TREE + f"\n<equality>\n  {equality}\n</equality>")
    with pytest.raises(InputError, match=re.escape(message)) as info:
        load_mjcf(path, actuated=["crank"])
    assert (info.value.source, info.value.row, info.value.field) == (str(path), 11, field)


def test_bad_trees_and_actuators_are_named(tmp_path):
    two_roots = write(tmp_path, TREE.replace("</body></worldbody>", '</body><body name="loose"/></worldbody>'),
                      "two.xml")
    with pytest.raises(InputError, match="Pinocchio 4.1 reads only the first") as info:
        load_mjcf(two_roots)
    assert info.value.field == "worldbody"
    included = write(tmp_path, TREE + '\n<include file="more.xml"/>', "inc.xml")
    with pytest.raises(InputError, match="does not follow includes"):
        load_mjcf(included)
    pinned = TREE + '\n<equality><connect body1="coupler_link" body2="rocker_link" anchor="0.3 0 0"/></equality>'
    with pytest.raises(InputError, match="actuator <motor> names joint 'elbow', which is not in the model"):
        load_mjcf(write(tmp_path, pinned + '\n<actuator><motor joint="elbow"/></actuator>', "act.xml"))
    with pytest.raises(InputError, match="actuated joint 'elbow' is not a joint of the model"):
        load_mjcf(write(tmp_path, pinned, "act2.xml"), actuated=["elbow"])
    with pytest.raises(InputError, match="needs its actuated joints"):
        load_mjcf(write(tmp_path, pinned, "act3.xml"))
    with pytest.raises(InputError, match="MJCF file not found"):
        load_mjcf(tmp_path / "missing.xml")
