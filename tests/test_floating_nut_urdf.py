"""URDF of the floating-nut hexapod: committed file, Pinocchio load, geometry round trip (spec test 13).

The closure-solved pose of the URDF model is checked in test_floating_nut_multibody.py.
"""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from lxml import etree

from robocal.errors import InputError
from robocal.systems.floating_nut.geometry import reference_fixture
from robocal.systems.floating_nut.kinematics import FloatingNutKinematics
from robocal.systems.floating_nut.urdf import build_urdf, geometry_from_urdf, write_urdf
from robocal.testing import assert_same_text_and_numbers

DEG = np.pi / 180
COMMITTED = Path(__file__).resolve().parents[1] / "urdf" / "floating_nut_hexapod.urdf"
# The URDF writes 15 significant digits: values of order 1 come back to about 1e-15.
ROUND_TRIP_TOL = 1e-14


def tilted_geometry(euler="ZYX-fixed"):
    g = reference_fixture()
    rng = np.random.default_rng(41)
    return g.with_changes(base_axes=g.base_axes + rng.normal(0, 0.4, (6, 3)),
                          plat_axes=g.plat_axes + rng.normal(0, 0.4, (6, 3)),
                          p0=[0.02, -0.01, 0.82, 3 * DEG, -2 * DEG, 4 * DEG], starts=[1, 2, 1, 3, 1, 2],
                          sigma=[1, -1, 1, 1, -1, -1], lead=[0.01, 0.005, 0.02, 0.01, 0.008, 0.012],
                          gear_ratio=[1, 2, 1, 1, 3, 1], euler=euler)


def test_committed_urdf_is_what_the_builder_writes():
    assert_same_text_and_numbers(COMMITTED.read_text(encoding="utf-8"), build_urdf(reference_fixture()), what=str(COMMITTED))


@pytest.mark.parametrize("geometry", [reference_fixture(), tilted_geometry(), tilted_geometry("XYZ-moving")],
                         ids=["fixture", "tilted", "tilted-XYZ"])
def test_geometry_round_trip(geometry, tmp_path):
    path = write_urdf(geometry, tmp_path / "hexapod.urdf")
    back = geometry_from_urdf(path, euler=geometry.euler)
    for field in ("b", "m", "p0", "lead", "base_axes", "plat_axes", "gear_ratio"):
        np.testing.assert_allclose(getattr(back, field), getattr(geometry, field), atol=ROUND_TRIP_TOL,
                                   err_msg=field)
    np.testing.assert_array_equal(back.sigma, geometry.sigma)
    np.testing.assert_array_equal(back.starts, geometry.starts)
    assert back.thread_hands == geometry.thread_hands
    # and the kinematics agree
    p = geometry.p0 + [0.03, -0.02, 0.05, 4 * DEG, -3 * DEG, 6 * DEG]
    np.testing.assert_allclose(FloatingNutKinematics(back).ik(p), FloatingNutKinematics(geometry).ik(p),
                               atol=1e-13)


def test_pinocchio_tree_has_the_geometry():
    g = tilted_geometry()
    text = build_urdf(g)
    model = pin.buildModelFromXML(text)
    assert model.nq == 7 + 6 * 6 and model.nv == 6 + 6 * 6
    data = model.createData()
    q = pin.neutral(model)
    ff = model.joints[model.getJointId("platform_float")].idx_q
    q[ff:ff + 7] = pin.SE3ToXYZQUAT(pin.SE3(g.home_rotation, g.p0[:3]))
    pin.forwardKinematics(model, data, q)
    kin = FloatingNutKinematics(g)
    for i in range(6):
        j1 = model.getJointId(f"leg{i + 1}_hooke_base_1")
        np.testing.assert_allclose(model.jointPlacements[j1].translation, g.b[i], atol=1e-14)
        # base-fixed axis of the first Hooke joint, in the base frame
        axis = model.jointPlacements[j1].rotation @ model.joints[j1].extract().axis
        np.testing.assert_allclose(axis, g.base_axes[i], atol=1e-14)
        # at zero joint angles every leg end sits on its platform anchor at the home pose
        end = data.oMi[model.getJointId(f"leg{i + 1}_hooke_plat_2")].translation
        np.testing.assert_allclose(end, g.p0[:3] + g.home_rotation @ g.m[i], atol=1e-14)
        stroke = model.getJointId(f"leg{i + 1}_stroke")
        assert model.joints[stroke].shortname() == "JointModelPZ"
        assert model.jointPlacements[stroke].translation[2] == pytest.approx(kin.home_lengths[i], abs=1e-14)
    assert not any("Mimic" in model.joints[j].shortname() for j in range(1, model.njoints))


def test_extra_elements_are_documented_format():
    root = etree.fromstring(build_urdf(reference_fixture()).encode())
    loops = root.findall("loop_joint")
    assert [lj.get("type") for lj in loops] == ["fixed"] * 6
    assert all(lj.find("link1") is not None and lj.find("link2").get("link") == "platform" for lj in loops)
    assert len(root.findall("actuated")) == 1
    screw = root.find("screw_transmission")
    assert {"stroke_joint", "roll_joint", "lead", "starts", "pitch", "hand", "nut_side", "sigma",
            "gear_ratio"} <= set(screw.keys())
    assert screw.get("hand") == "left" and screw.get("sigma") == "1"     # fixture: sigma = +1


def test_reading_a_foreign_urdf_is_a_clear_error(tmp_path):
    path = tmp_path / "other.urdf"
    path.write_text('<robot name="x"><link name="base"/></robot>')
    with pytest.raises(InputError, match="leg1_hooke_base_1") as info:
        geometry_from_urdf(path)
    assert str(path) in str(info.value)
    with pytest.raises(InputError, match="XML"):
        geometry_from_urdf("<robot><unclosed></robot>")
