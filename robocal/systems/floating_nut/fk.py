"""Single-pose Newton FK of the floating-nut hexapod, written against numpy's per-call overhead.

Same method and iterates as the batch `FloatingNutKinematics.fk` (docs/floating_nut_hexapod.md: Newton in the pose
p = [x y z alpha beta gamma] on the compensated lengths with the analytic J_c, stop when
|e|_inf < tol, then one chord step), with a few dozen numpy calls per Newton step, not hundreds:

* m = [R (9, row-major), t (3), 1]; per leg, the five scalars the compensated IK needs,
      ac = a.(R c),  au = a.u,  uu = u.u,  cu = (R c).u,  acu = (a x R c).u,   u = t + R m_i - b_i,
  are quadratic forms q = m^T Q m, so ONE product gives Q m (30, 13), the values q = (Q m) m and
  the gradients dq/dm = 2 Q m;
* with them (Binet-Cauchy, and (n_b x n_m) = -((a x u).c) u): n_b.n_m = ac uu - au cu and
  (n_b x n_m).s = l acu, l = sqrt(uu), so phi = atan2(l acu, ac uu - au cu) and
  J_c = sum_k (dl_c/dq_k) dq_k/dm dm/dp with scalar weights per leg;
* a cold solve starts with the second-order home step (home_step.py); R and dR/d(angles) are plain floats;
* the five weights of each leg come from one product with a constant (60, 30) map, and J = G dm/dp with
  G (6, 13) the weighted rows of Q m.
"""
from __future__ import annotations

import logging
import math

import numpy as np
from scipy.linalg.lapack import dgesv, dgetri, dgetrs

from robocal.systems.floating_nut.results import SINGULAR_TOL, FKNotConverged, FKResult, wrap_angle

# rows of the value blocks, each 6 legs: the order lets ac uu - au cu be one product of two slices
AC, AU, UU, CU, ACU = range(5)

log = logging.getLogger(__name__)


def rotation_zyx(a, b, g):
    """R = Rz(g) Ry(b) Rx(a) (9 floats, row-major) and dR/da, dR/db, dR/dg (9 floats each); tuples, so
    that floating_nut_fk_compiled can jit this very function."""
    ca, sa, cb, sb, cg, sg = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(g), math.sin(g)
    r00, r10 = cg * cb, sg * cb
    r01, r02 = cg * sb * sa - sg * ca, cg * sb * ca + sg * sa
    r11, r12 = sg * sb * sa + cg * ca, sg * sb * ca - cg * sa
    r21, r22 = cb * sa, cb * ca
    return ((r00, r01, r02, r10, r11, r12, -sb, r21, r22),
            (0.0, r02, -r01, 0.0, r12, -r11, 0.0, r22, -r21),                        # R skew(e_x)
            (-cg * sb, cg * r21, cg * r22, -sg * sb, sg * r21, sg * r22, -cb, -sb * sa, -sb * ca),
            (-r10, -r11, -r12, r00, r01, r02, 0.0, 0.0, 0.0))                         # skew(e_z) R


def rotation_xyz(a, b, g):
    """R = Rx(a) Ry(b) Rz(g) (9 floats, row-major) and dR/da, dR/db, dR/dg (9 floats each)."""
    ca, sa, cb, sb, cg, sg = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(g), math.sin(g)
    r00, r01 = cb * cg, -cb * sg
    r10, r11, r12 = ca * sg + sa * sb * cg, ca * cg - sa * sb * sg, -sa * cb
    r20, r21, r22 = sa * sg - ca * sb * cg, sa * cg + ca * sb * sg, ca * cb
    return ((r00, r01, sb, r10, r11, r12, r20, r21, r22),
            (0.0, 0.0, 0.0, -r20, -r21, -r22, r10, r11, r12),                        # skew(e_x) R
            (-sb * cg, sb * sg, cb, sa * cb * cg, -sa * cb * sg, sa * sb, -ca * cb * cg, ca * cb * sg, -ca * sb),
            (r01, -r00, 0.0, r11, -r10, 0.0, r21, -r20, 0.0))                         # R skew(e_z)


ROTATIONS = {"ZYX-fixed": rotation_zyx, "XYZ-moving": rotation_xyz}


def _quadratic_forms(b, m, a, c) -> np.ndarray:
    """Q (13, 5 * 6 * 13) with q_r = m^T Q_r m for the rows (AC, AU, UU, CU, ACU) x legs, from
    homogeneous degree-2 polynomials in m = [R, t, w] (exact for any m, so Q is too)."""
    def scalars(mv):                                   # mv (K, 13) -> (K, 5, 6)
        Rg, tg, w = mv[:, :9].reshape(-1, 3, 3), mv[:, 9:12], mv[:, 12:]
        u = tg[:, None] + m @ Rg.transpose(0, 2, 1) - w[:, :, None] * b
        rc = c @ Rg.transpose(0, 2, 1)
        dot = lambda x, y: np.einsum("...i,...i->...", x, y)  # noqa: E731
        return np.stack([w * dot(a, rc), w * dot(a, u), dot(u, u), dot(rc, u), dot(np.cross(a, rc), u)], 1)
    eye = np.eye(13)
    diag = scalars(eye)                                               # f(e_a) = Q_aa
    pairs = scalars((eye[:, None] + eye[None]).reshape(-1, 13)).reshape(13, 13, 5, 6)
    Q = 0.5 * (pairs - diag[:, None] - diag[None])                    # Q_ab = (f(e_a + e_b) - Q_aa - Q_bb) / 2
    Q[np.arange(13), np.arange(13)] = diag
    return np.ascontiguousarray(Q.transpose(0, 2, 3, 1).reshape(13, -1))   # [a, (row, leg, b)]


def _weight_maps():
    """Constant maps of the Jacobian weights (see SinglePoseFK._jacobian).

    J = sum over the five quantities k of w_k (Q m)_k dm/dp (dq = 2 (Q m) dm: the 2 is in w), with
    hy = gain y / r2, hxl = gain x / (r2 l), r2 = x^2 + y^2:
        w_ac = -2 hy uu,  w_au = 2 hy cu,  w_cu = 2 hy au,  w_acu = 2 hxl uu,
        w_uu = 1 / l + hxl acu - 2 hy ac.
    So w (5, 6) = hy * (P q) + hxl * (X q), plus 1 / l on the uu row: returns [P; X] (60, 30), one product.
    """
    hy_terms = ((AC, UU, -2.0), (AU, CU, 2.0), (CU, AU, 2.0), (UU, AC, -2.0))   # (weight, quantity, coefficient)
    hxl_terms = ((ACU, UU, 2.0), (UU, ACU, 1.0))
    maps = np.zeros((2, 30, 30))
    for block, terms in enumerate((hy_terms, hxl_terms)):
        for dst, src, coef in terms:
            for j in range(6):
                maps[block, 6 * dst + j, 6 * src + j] = coef
    return maps.reshape(60, 30)


def _angle_slots():
    """Flat indices in dm/dp (13, 6) of dR/dalpha, dR/dbeta, dR/dgamma (9 rows each, columns 3-5)."""
    return np.array([6 * r + 3 + k for k in range(3) for r in range(9)])


class SinglePoseFK:
    """Tables and the Newton loop of one FloatingNutKinematics for one pose at a time."""

    def __init__(self, kin):
        g = kin.geometry
        self.kin = kin
        self.rotation = ROTATIONS[g.euler]
        self.forms = _quadratic_forms(g.b, g.m, kin._a, kin._c)
        self.gain, self.phi0, self.l0, self.p0 = kin._gain, kin._phi0, kin._l0, g.p0.tolist()
        self.weights = _weight_maps()
        self.ones5 = np.ones(5)
        self.dm_home = np.zeros((13, 6))              # dm/dp: translation rows 9-11 are unit, angles per pose
        self.dm_home[9:12, :3] = np.eye(3)
        self.angle_slots = _angle_slots()
        self.start = kin.home_step()
        # Newton matrices at p0 and their LU (the home step converges at once near p0: a chord step uses them)
        self.home = {}
        for full in (True, False):
            J0 = kin.jacobian(g.p0) if full else kin.length_and_roll_jacobians(g.p0)[0]
            lu, piv, inv, info = dgesv(J0, np.eye(6))
            self.home[full] = None if info else (J0, lu, piv, inv)

    def _evaluate(self, p, L, compensate):
        """m-lift at pose p: Q m (30, 13), q (30,), l, x, y, dR/d(angles) (27 floats), residual e."""
        R, dRa, dRb, dRg = self.rotation(p[3], p[4], p[5])
        m = np.array(R + (p[0], p[1], p[2], 1.0))
        Qm = m.dot(self.forms).reshape(30, 13)
        q = Qm.dot(m)
        l = np.sqrt(q[12:18])                                  # UU
        if not compensate:
            return Qm, q, l, None, None, dRa + dRb + dRg, L - l
        x, y = q[:6] * q[12:18] - q[6:12] * q[18:24], l * q[24:]   # ac uu - au cu, l acu
        theta = np.arctan2(y, x) - self.phi0                # theta = wrap(phi - phi0), eq. (2')
        th = theta.tolist()
        if max(th) > math.pi or min(th) <= -math.pi:
            theta = wrap_angle(theta)
        return Qm, q, l, x, y, dRa + dRb + dRg, (L - l) - self.gain * theta

    def _jacobian(self, Qm, q, l, x, y, dR, full, dm=None):
        """J_c (full) or J_l = dl/dp at the evaluated pose, (6, 6): J = G dm/dp with G (6, 13) the
        per-leg weights of `_weight_maps` on the rows of Q m (dq = 2 (Q m) dm); dm: a dm/dp buffer to fill
        (one per solve), or None for a new one."""
        il = 1.0 / l
        if full:
            k = self.gain / (x * x + y * y)
            w = self.weights.dot(q).reshape(2, 5, 6)
            w = w[0] * (k * y) + w[1] * ((k * x) * il)
            w[UU] += il
            G = self.ones5.dot((w.reshape(30, 1) * Qm).reshape(5, 78)).reshape(6, 13)
        else:
            G = il[:, None] * Qm[12:18]                        # dl = d(uu) / (2 l)
        dm = self.dm_home.copy() if dm is None else dm
        dm.put(self.angle_slots, dR)
        return G.dot(dm)

    def _check_singular(self, p, q, x=None, y=None):
        """Raise SingularHookeError as the batch path does: (x^2 + y^2) / uu^2 = sin_b^2 sin_m^2 (the
        squared sines of the axis-strut angles, each <= 1), so a ratio >= SINGULAR_TOL^2 clears both."""
        uu = q[12:18]
        if x is None:
            x, y = q[:6] * uu - q[6:12] * q[18:24], np.sqrt(uu) * q[24:]
        if not min(((x * x + y * y) / (uu * uu)).tolist()) >= SINGULAR_TOL ** 2:
            self.kin._terms(np.array([p]), what="FK iterate of sample")   # raises, naming side and leg

    def solve(self, L, p_init, compensate, jacobian, tol, max_iter, warn_condition) -> FKResult:
        """`FloatingNutKinematics.fk` for lengths L (6,) and p_init (6 floats) or None (p0).

        The Hooke-singularity test runs on the solution and before any failure is reported.
        """
        full = compensate and jacobian == "full"
        home = self.home[full] if p_init is None and self.start.ready(compensate) else None
        p = list(self.p0 if p_init is None else p_init)
        history, iterations, J, lu, piv, k = [], 0, None, None, None, 0
        dm = self.dm_home.copy()
        if home is not None:
            # cold start: the residual at p0 is L - l(p0) (theta(p0) = 0); the second-order home step
            # (home_step.py) counts as the first iteration
            e = L - self.l0
            res = max(map(abs, e.tolist()))
            history.append(res)
            if res < tol:
                return FKResult(np.array(p), 0, res, history)
            if max_iter == 0:
                raise _not_converged(max_iter, res, tol)
            J, lu, piv, _ = home          # a chord step may use J(p0) if the home step already converges
            p = [a + d for a, d in zip(p, self.start.step(e, compensate).tolist())]
            iterations = k = 1
        while True:
            Qm, q, l, x, y, dR, e = self._evaluate(p, L, compensate)
            el = e.tolist()
            res = max(map(abs, el))
            history.append(res)
            if res < tol and math.isfinite(sum(el)):   # the sum catches a NaN that max() may skip
                self._check_singular(p, q, x, y)
                if J is not None:   # chord step with the last matrix: pose error to round-off
                    p = [a + d for a, d in zip(p, dgetrs(lu, piv, e)[0].tolist())]
                break
            if k == max_iter:
                self._check_singular(p, q, x, y)
                raise _not_converged(max_iter, res, tol)
            J = self._jacobian(Qm, q, l, x, y, dR, full, dm)
            lu, piv, step, info = dgesv(J, e)
            step = step.tolist()
            if info or not math.isfinite(sum(step)):
                self._check_singular(p, q, x, y)
                raise FKNotConverged("FK of sample 0: singular Jacobian", sample=0)
            p = [a + d for a, d in zip(p, step)]
            iterations += 1
            k += 1
        if warn_condition is not None and iterations > 0:
            # cond_2(J) <= |J|_F |J^-1|_F: the exact (20 times dearer) cond only above the threshold
            inv = dgetri(lu, piv)[0].ravel()
            flat = J.ravel()
            if math.sqrt(flat.dot(flat) * inv.dot(inv)) > warn_condition:
                cond = np.linalg.cond(J)
                if cond > warn_condition:
                    log.warning("FK: Jacobian condition number %.3g near the solution of sample 0 "
                                "(close to a singularity)", cond)
        return FKResult(np.array(p), iterations, res, history)


def _not_converged(max_iter, res, tol):
    return FKNotConverged(f"FK of sample 0 did not converge in {max_iter} iterations "
                          f"(residual {res:.3g} m, tolerance {tol:g} m)", sample=0)
