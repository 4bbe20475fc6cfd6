"""plausible_bounds.py: the bounding ellipsoid holds its link's geometry and the CAD body, a body outside it
breaks the row, and the consistent fit keeps every body inside its bounds."""
import numpy as np
import pinocchio as pin

from robocal.dynamics.inertial import parameter_vector
from robocal.dynamics.plausible_bounds import BodyBound, body_bounds, linear_bounds
from robocal.dynamics.reduced_model import reduced_model
from tiago_dynamics_cases import JOINTS, urdf_path


def test_the_ellipsoid_row_is_the_second_moment_test():
    """tr(Q J) = integral of 1 - (x - c)^T A (x - c) dm: a point mass inside the ellipsoid passes, outside fails."""
    bound = BodyBound("j", 1.0, (0.5, 2.0), np.array([0.1, 0.0, 0.0]), np.array([0.2, 0.1, 0.1]), "config")
    rows = linear_bounds([bound], 1, {"j": 0})
    for x, inside in (([0.25, 0.0, 0.0], True), ([0.35, 0.0, 0.0], False), ([0.1, 0.0, 0.09], True),
                      ([0.1, 0.0, 0.11], False)):
        point = pin.Inertia(1.0, np.array(x), np.zeros((3, 3))).toDynamicParameters()
        slack = rows.slack(point)
        assert (slack[-1] >= 0) == inside
        np.testing.assert_allclose(slack[:2], [0.5, 1.0])           # mass 1 kg inside [0.5, 2]


def test_the_tiago_bounds_hold_the_cad_bodies_and_the_collision_boxes():
    model = reduced_model(urdf_path(), JOINTS)
    bounds = body_bounds(model, urdf_path().read_text())
    rows = linear_bounds(bounds, len(bounds), {b.joint: i for i, b in enumerate(bounds)})
    assert np.all(rows.slack(parameter_vector(model)) > 0)          # the CAD model is plausible by its own bounds
    # arm_7's body carries the wrist sensor's cylinders (collision primitives): their corners lie inside
    arm7 = next(b for b in bounds if b.joint == "arm_7_joint")
    assert "collision primitives" in arm7.source
    frame = model.frames[model.getFrameId("wrist_ft_link")]
    corner = frame.placement.act(np.array([0.0225, 0.0225, 0.0157 / 2]))
    assert np.sum(((corner - arm7.center) / arm7.semi_axes) ** 2) <= 1.0
