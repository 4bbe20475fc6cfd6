"""Independent multibody check (spec seed-002 §7.3 tests 6, 7, 13 and §7.4).

A closed-loop Pinocchio model with a real helical nut joint (JointModelHZ) is driven by motor
angles; solving its 36 loop-closure equations by Newton must give the same platform pose and nut
roll as the closed-form compensated kinematics. The model shares no code with robocal's formulas:
only the geometry numbers. The URDF written by the builder is checked the same way.
"""
import numpy as np
import pinocchio as pin
import pytest
from lxml import etree

from robocal.systems.floating_nut.geometry import reference_fixture, rotation_matrices
from robocal.systems.floating_nut.kinematics import FloatingNutKinematics
from robocal.systems.floating_nut.urdf import build_urdf

DEG = np.pi / 180
TWO_PI = 2 * np.pi


def unit(v):
    return v / np.linalg.norm(v)


class HelicalHexapod:
    """Spec §7.4: free-flying platform; per leg U (2R) - motor RZ - helical nut HZ - U (2R)."""

    def __init__(self, g):
        self.g = g
        R0, t0 = rotation_matrices(g.p0[3:], g.euler), g.p0[:3]
        model = pin.Model()
        plat = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "platform")
        self.closures, self.motor, self.nut, self.hooke, motor_v = [], [], [], [], []
        for i in range(6):
            f_m = model.addFrame(pin.Frame(f"M_{i}", plat, 0, pin.SE3(np.eye(3), g.m[i]), pin.FrameType.OP_FRAME))
            u0 = t0 + R0 @ g.m[i] - g.b[i]
            s0 = unit(u0)
            a2h = unit(np.cross(g.base_axes[i], s0))
            R_H = np.column_stack([a2h, np.cross(s0, a2h), s0])
            c0 = R0 @ g.plat_axes[i]
            pitch = -g.sigma[i] * g.lead[i] / TWO_PI       # right-hand thread (sigma=-1): positive pitch
            j1 = model.addJoint(0, pin.JointModelRevoluteUnaligned(R_H.T @ g.base_axes[i]), pin.SE3(R_H, g.b[i]),
                                f"u_b1_{i}")
            j2 = model.addJoint(j1, pin.JointModelRX(), pin.SE3.Identity(), f"u_b2_{i}")
            j3 = model.addJoint(j2, pin.JointModelRZ(), pin.SE3.Identity(), f"motor_{i}")
            j4 = model.addJoint(j3, pin.JointModelHZ(pitch), pin.SE3(np.eye(3), np.array([0, 0, np.linalg.norm(u0)])),
                                f"nut_{i}")
            j5 = model.addJoint(j4, pin.JointModelRevoluteUnaligned(R_H.T @ unit(np.cross(c0, s0))),
                                pin.SE3.Identity(), f"u_m1_{i}")
            j6 = model.addJoint(j5, pin.JointModelRevoluteUnaligned(R_H.T @ c0), pin.SE3.Identity(), f"u_m2_{i}")
            f_e = model.addFrame(pin.Frame(f"end_{i}", j6, 0, pin.SE3(R_H.T @ R0, np.zeros(3)),
                                           pin.FrameType.OP_FRAME))
            self.closures.append((f_m, f_e))
            self.motor.append(model.joints[j3].idx_q)
            motor_v.append(model.joints[j3].idx_v)
            self.nut.append(model.joints[j4].idx_q)
            self.hooke.append([model.joints[j].idx_q for j in (j1, j2, j5, j6)])
        self.model, self.data = model, model.createData()
        self.free_v = np.setdiff1d(np.arange(model.nv), motor_v)      # q has 7 platform entries, v has 6

    def start(self, motor_angles):
        """Home assembly with the motors turned; nut turned back (chi = -psi) to pick the right branch."""
        q = pin.neutral(self.model)
        q[:7] = pin.SE3ToXYZQUAT(pin.SE3(rotation_matrices(self.g.p0[3:], self.g.euler), self.g.p0[:3]))
        q[self.motor] = motor_angles
        q[self.nut] = -np.asarray(motor_angles)
        return q

    def solve(self, motor_angles, tol=1e-14, max_iter=30):
        """Assemble the loops with the motors held: (q, Newton iterations)."""
        q = self.start(motor_angles)
        return newton(self.model, self.data, self.closures, q, self.free_v, tol=tol, max_iter=max_iter)


def closure_terms(model, data, closures, q):
    """Stacked log6 closure errors and their exact Jacobian (6 rows per closure)."""
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    rows, jac = [], []
    for f1, f2 in closures:
        rel = data.oMf[f1].actInv(data.oMf[f2])
        J1 = pin.getFrameJacobian(model, data, f1, pin.LOCAL)
        J2 = pin.getFrameJacobian(model, data, f2, pin.LOCAL)
        rows.append(pin.log6(rel).vector)
        jac.append(pin.Jlog6(rel) @ (J2 - rel.inverse().action @ J1))
    return np.concatenate(rows), np.vstack(jac)


def newton(model, data, closures, q, free_v, extra=None, tol=1e-14, max_iter=30):
    """Newton on the closures (+ optional linear rows extra(q) -> (r, J)) over velocity indices free_v."""
    for it in range(max_iter):
        r, J = closure_terms(model, data, closures, q)
        if extra is not None:
            r_x, J_x = extra(q)
            r, J = np.concatenate([r, r_x]), np.vstack([J, J_x])
        if np.abs(r).max() < tol:
            return q, it
        dv = np.zeros(model.nv)
        dv[free_v] = -np.linalg.solve(J[:, free_v], r)
        q = pin.integrate(model, q, dv)
    raise AssertionError(f"closure Newton did not converge: residual {np.abs(r).max():.3g}")


def platform(q, start=0):
    """Platform position and rotation from the free-flyer entries q[start:start+7]."""
    M = pin.XYZQUATToSE3(q[start:start + 7])
    return M.translation.copy(), M.rotation.copy()


def tilted_geometry():
    """Non-radial axes, tilted home pose, mixed thread hands and leads."""
    g = reference_fixture()
    rng = np.random.default_rng(31)
    return g.with_changes(base_axes=g.base_axes + rng.normal(0, 0.4, (6, 3)),
                          plat_axes=g.plat_axes + rng.normal(0, 0.4, (6, 3)),
                          p0=[0.02, -0.01, 0.82, 3 * DEG, -2 * DEG, 4 * DEG],
                          sigma=[1, -1, 1, 1, -1, -1], lead=[0.01, 0.005, 0.02, 0.01, 0.008, 0.012])


def tangential_geometry():
    g = reference_fixture()
    z = np.array([0, 0, 1.0])
    return g.with_changes(base_axes=np.cross(z, g.b), plat_axes=np.cross(z, g.m))


@pytest.fixture(scope="module")
def fixture_model():
    return HelicalHexapod(reference_fixture())


def test_home_assembles(fixture_model):
    r, J = closure_terms(fixture_model.model, fixture_model.data, fixture_model.closures,
                         fixture_model.start(np.zeros(6)))
    assert np.abs(r).max() < 1e-15
    assert np.linalg.matrix_rank(J[:, fixture_model.free_v]) == 36


@pytest.mark.parametrize("geometry", [reference_fixture(), tilted_geometry()], ids=["fixture", "tilted"])
def test_multibody_matches_closed_form(geometry):
    mb = HelicalHexapod(geometry)
    kin = FloatingNutKinematics(geometry)
    rng = np.random.default_rng(32)
    worst_t = worst_r = worst_roll = 0.0
    for _ in range(10):
        psi = rng.uniform(-6, 6, 6) * TWO_PI                       # encoder angles, +-6 turns
        q, iters = mb.solve(geometry.sigma * psi)                  # joint sign: see HelicalHexapod pitch
        t, R = platform(q)
        fk = kin.fk(kin.motor_to_lengths(psi))
        worst_t = max(worst_t, np.abs(t - fk.pose[:3]).max())
        worst_r = max(worst_r, np.abs(R - rotation_matrices(fk.pose[3:], geometry.euler)).max())
        roll = q[mb.motor] + q[mb.nut]                              # psi_i + chi_i, nut roll vs housing
        worst_roll = max(worst_roll, np.abs(roll - kin.nut_rotation(fk.pose)).max())
        assert iters <= 8
    assert worst_t < 1e-12 and worst_r < 1e-12 and worst_roll < 1e-12


def test_tangential_hooke_axes_need_the_general_formula():
    g = tangential_geometry()
    mb = HelicalHexapod(g)
    general = FloatingNutKinematics(g)
    radial = FloatingNutKinematics(reference_fixture())            # the patent's implicit assumption
    pose = np.array([0.05, -0.05, 0.85, 5 * DEG, -5 * DEG, 8 * DEG])
    psi = general.lengths_to_motor(general.ik(pose))
    q, _ = mb.solve(psi)
    t, R = platform(q)
    true_roll = q[mb.motor] + q[mb.nut]
    assert np.abs(t - pose[:3]).max() < 1e-12
    assert np.abs(R - rotation_matrices(pose[3:])).max() < 1e-12
    np.testing.assert_allclose(general.nut_rotation(pose), true_roll, atol=1e-12)
    assert np.abs(radial.nut_rotation(pose) - true_roll).max() > 1 * DEG     # off by degrees
    fk = general.fk(general.motor_to_lengths(psi))
    assert np.abs(fk.pose[:3] - t).max() < 1e-12


def test_hooke_angles_match_multibody(fixture_model):
    kin = FloatingNutKinematics(reference_fixture())
    psi = np.random.default_rng(33).uniform(-3, 3, 6) * TWO_PI
    q, _ = fixture_model.solve(psi)
    pose = kin.fk(kin.motor_to_lengths(psi)).pose
    ours = kin.hooke_angles(pose)                                   # (6, 4): q1 q2 q5 q6
    theirs = q[np.array(fixture_model.hooke)]                       # u_b1 u_b2 u_m1 u_m2
    assert np.abs(ours).max() > 1 * DEG
    np.testing.assert_allclose(ours[:, :2], theirs[:, :2], atol=1e-12)
    # the platform joint is measured platform -> rod; the chain runs rod -> platform
    np.testing.assert_allclose(ours[:, 2:], -theirs[:, 2:], atol=1e-12)


# ---- the URDF written by the builder, closed with its own <loop_joint> / <screw_transmission> ----
class UrdfHexapod:
    """Pinocchio tree from the URDF text; closures and screw rows read here with lxml."""

    def __init__(self, text):
        root = etree.fromstring(text.encode("utf-8"))
        self.model = pin.buildModelFromXML(text)
        self.data = self.model.createData()
        self.ff = self.model.joints[self.model.getJointId("platform_float")].idx_q   # urdfdom orders children
        self.closures = []
        for loop in root.findall("loop_joint"):
            assert loop.get("type") == "fixed"
            self.closures.append(tuple(self._frame(loop.find(tag)) for tag in ("link1", "link2")))
        self.screws = []
        for s in root.findall("screw_transmission"):
            stroke = self.model.joints[self.model.getJointId(s.get("stroke_joint"))].idx_v
            roll = self.model.joints[self.model.getJointId(s.get("roll_joint"))].idx_v
            self.screws.append((stroke, roll, float(s.get("lead")), int(s.get("sigma")), float(s.get("gear_ratio"))))
        actuated = root.find("actuated").get("joints").split()
        assert actuated == [s.get("stroke_joint") for s in root.findall("screw_transmission")]

    def _frame(self, el):
        body = self.model.getFrameId(el.get("link"), pin.FrameType.BODY)
        parent = self.model.frames[body]
        xyz = np.array(el.get("xyz").split(), dtype=float)
        rpy = np.array(el.get("rpy").split(), dtype=float)
        placement = parent.placement * pin.SE3(pin.rpy.rpyToMatrix(rpy), xyz)
        return self.model.addFrame(pin.Frame(f"{el.get('link')}_loop_{len(self.closures)}", parent.parentJoint,
                                             body, placement, pin.FrameType.OP_FRAME))

    def solve(self, psi, p_start):
        """Assemble with motor angles psi: rows q_stroke + sigma L/2pi q_roll - L/2pi psi/gear = 0."""
        self.data = self.model.createData()
        rows = np.zeros((6, self.model.nv))
        target = np.zeros(6)
        for k, (stroke, roll, lead, sigma, gear) in enumerate(self.screws):
            rows[k, stroke], rows[k, roll] = 1.0, sigma * lead / TWO_PI
            target[k] = lead / TWO_PI * psi[k] / gear
        q = pin.neutral(self.model)
        q[self.ff:self.ff + 7] = pin.SE3ToXYZQUAT(pin.SE3(rotation_matrices(p_start[3:]), p_start[:3]))
        extra = lambda q: (rows @ pin.difference(self.model, pin.neutral(self.model), q) - target, rows)  # noqa: E731
        return newton(self.model, self.data, self.closures, q, np.arange(self.model.nv), extra=extra)


def test_urdf_closure_solve_matches_multibody(fixture_model):
    g = reference_fixture()
    urdf = UrdfHexapod(build_urdf(g))
    assert urdf.model.nq == 7 + 36 and len(urdf.closures) == 6
    psi = np.random.default_rng(34).uniform(-6, 6, 6) * TWO_PI
    q_ref, _ = fixture_model.solve(psi)
    q, _ = urdf.solve(psi, g.p0)
    t, R = platform(q, urdf.ff)
    t_ref, R_ref = platform(q_ref)
    assert np.abs(t - t_ref).max() < 1e-12 and np.abs(R - R_ref).max() < 1e-12
    roll = np.array([q[urdf.model.joints[urdf.model.getJointId(f"leg{i}_nut_roll")].idx_q] for i in range(1, 7)])
    np.testing.assert_allclose(roll, q_ref[fixture_model.motor] + q_ref[fixture_model.nut], atol=1e-12)
