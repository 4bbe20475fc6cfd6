"""Optional numba kernel of the single-pose Newton FK of the floating-nut hexapod.

Same method and iterates as `SinglePoseFK.solve` (floating_nut_fk.py): cold start with the
second-order home step (home_step.py), Newton on l_c (J_c) or l (J_l, "uncompensated"), stop when |e|_inf < tol,
then one chord step with the last LU. Scalar loops over the 6 legs and a 6x6 LU with partial
pivoting written out (np.linalg.solve in numba goes through LAPACK and costs more at this size).
The per-leg scalars are those of floating_nut_fk.py, computed directly instead of by quadratic forms:
    u = t + R m - b,  rc = R c,  ac = a.rc,  au = a.u,  uu = u.u,  cu = rc.u,  acu = (a x rc).u,
    l = sqrt(uu),  x = ac uu - au cu,  y = l acu,  phi = atan2(y, x).

numba is imported only when a kinematics object first solves one pose with the kernel enabled:
`FloatingNutKinematics(..., use_numba=False)` or the environment variable ROBOCAL_NO_NUMBA=1 keep
the numpy path, and without numba robocal runs as before. Install with `pip install robocal[fast]`.
"""
from __future__ import annotations

import math

import numpy as np

from robocal.model.kernel_jit import jit_in_place, numba_chosen
from robocal.systems.floating_nut.fk import SinglePoseFK, rotation_xyz, rotation_zyx
from robocal.systems.floating_nut.results import SINGULAR_TOL, FKResult

EULER_CODES = {"ZYX-fixed": 0, "XYZ-moving": 1}
# kernel status; any failure makes the numpy solver rerun the same iterates and raise its own error
OK, NOT_CONVERGED, SINGULAR_HOOKE, SINGULAR_JACOBIAN, HISTORY_FULL = range(5)
HISTORY_CAP = 64                 # residuals kept by the kernel; a longer run goes to the numpy path
# columns of the per-leg constants and of the per-leg work table
B, M, A, C, PHI0, L0, GAIN = 0, 3, 6, 9, 12, 13, 14
U, RC, AXRC, AC, AU, UU, CU, ACU, LEN, X, Y, THETA = 0, 3, 6, 9, 10, 11, 12, 13, 14, 15, 16, 17


def numba_wanted(use_numba: bool | None) -> bool:
    """use_numba, or for None: ROBOCAL_NO_NUMBA is unset (or 0) and numba imports (robocal.model.kernel_jit)."""
    return numba_chosen(use_numba, _compile)


def single_pose_solver(kin, use_numba: bool | None = None) -> SinglePoseFK:
    """The single-pose FK for `kin`: the numba one when wanted (see `numba_wanted`), else numpy."""
    return CompiledSinglePoseFK(kin) if numba_wanted(use_numba) else SinglePoseFK(kin)


class CompiledSinglePoseFK(SinglePoseFK):
    """`SinglePoseFK` whose `solve` runs in the numba kernel (the numpy tables stay for fallbacks)."""

    def __init__(self, kin):
        _compile()                       # ImportError here when use_numba=True and numba is missing
        super().__init__(kin)
        g = kin.geometry
        per_leg = (g.b, g.m, kin._a, kin._c, kin._phi0[:, None], kin._l0[:, None],
                   np.broadcast_to(kin._gain, (6,))[:, None])
        self.consts = np.ascontiguousarray(np.hstack(per_leg), dtype=float)
        self.euler = EULER_CODES[g.euler]
        self.p0_array = np.array(self.p0, dtype=float)
        # home step per (full, compensate): [J0, LU of J0, model J^-1 at p0], 0-based pivots, curvature (36, 6)
        self.tables = {}
        for full, compensate in ((True, True), (False, True), (False, False)):
            home = self.home[full]
            if home is not None and self.start.ready(compensate):
                J0, lu, piv, _ = home
                self.tables[full, compensate] = (
                    np.ascontiguousarray([J0, lu, self.start.inverse[compensate]], dtype=float),
                    np.ascontiguousarray(piv, dtype=np.int64) - 1, self.start.curvature[compensate])
        self.no_home = (np.zeros((3, 6, 6)), np.zeros(6, dtype=np.int64), np.zeros((36, 6)))

    def solve(self, L, p_init, compensate, jacobian, tol, max_iter, warn_condition) -> FKResult:
        full = compensate and jacobian == "full"
        cold = p_init is None and (full, compensate) in self.tables
        home, piv, curvature = self.tables[full, compensate] if cold else self.no_home
        p = self.p0_array.copy() if p_init is None else np.array(p_init, dtype=float)
        hist = np.empty(HISTORY_CAP)
        status, iterations, res, n, bound = _newton(
            np.array(L, dtype=float), p, cold, self.consts, home, piv, curvature, self.euler,
            compensate, full, float(tol), float(max_iter), warn_condition is not None, hist)
        if status != OK or (warn_condition is not None and bound > warn_condition):
            # failures and condition warnings: the numpy solver reruns the same iterates and raises
            # (or logs) exactly as without numba; no message text is duplicated here
            return super().solve(L, p_init, compensate, jacobian, tol, max_iter, warn_condition)
        return FKResult(p, iterations, res, hist[:n].tolist())


# ---- kernel (plain Python until `_compile` jits it in place) ---------------------------------

def _rotation(euler, a, b, g):
    """R (9, row-major) and dR/da, dR/db, dR/dg: the numpy path's own functions, jitted with the kernel."""
    return rotation_zyx(a, b, g) if euler == 0 else rotation_xyz(a, b, g)


def _rotate(R, v, i0):
    """R (9-tuple, row-major) @ v[i0:i0+3], as a tuple."""
    x, y, z = v[i0], v[i0 + 1], v[i0 + 2]
    return (R[0] * x + R[1] * y + R[2] * z, R[3] * x + R[4] * y + R[5] * z, R[6] * x + R[7] * y + R[8] * z)


def _evaluate(p, L, consts, R, compensate, legs, e):
    """Per-leg scalars (work table `legs`) and the residual e = L - l_c(p) (or L - l)."""
    out_of_range = False
    for i in range(6):
        w, k = legs[i], consts[i]
        rm, rc = _rotate(R, k, M), _rotate(R, k, C)
        for r in range(3):
            w[U + r] = p[r] + rm[r] - k[B + r]
            w[RC + r] = rc[r]
        w[AXRC] = k[A + 1] * w[RC + 2] - k[A + 2] * w[RC + 1]
        w[AXRC + 1] = k[A + 2] * w[RC] - k[A] * w[RC + 2]
        w[AXRC + 2] = k[A] * w[RC + 1] - k[A + 1] * w[RC]
        ac = au = uu = cu = acu = 0.0
        for r in range(3):
            ac += k[A + r] * w[RC + r]
            au += k[A + r] * w[U + r]
            uu += w[U + r] * w[U + r]
            cu += w[RC + r] * w[U + r]
            acu += w[AXRC + r] * w[U + r]
        l = math.sqrt(uu)
        w[AC], w[AU], w[UU], w[CU], w[ACU], w[LEN] = ac, au, uu, cu, acu, l
        w[X], w[Y] = ac * uu - au * cu, l * acu
        e[i] = L[i] - l
        if compensate:
            theta = math.atan2(w[Y], w[X]) - k[PHI0]
            out_of_range |= theta > math.pi or theta <= -math.pi
            w[THETA] = theta
    if compensate:
        for i in range(6):
            theta = legs[i, THETA]
            if out_of_range:         # as the numpy path: all legs wrapped when one is out of (-pi, pi]
                theta = -((math.pi - theta) % (2.0 * math.pi) - math.pi)
            e[i] -= consts[i, GAIN] * theta


def _jacobian(legs, consts, dR, full, J):
    """J_c (full) or J_l: J = sum_k c_k dq_k/dp over q = (ac, au, uu, cu, acu), per leg."""
    for i in range(6):
        w, k = legs[i], consts[i]
        ac, au, uu, cu, acu, l, x, y = w[AC], w[AU], w[UU], w[CU], w[ACU], w[LEN], w[X], w[Y]
        c_uu = 0.5 / l                                   # dl = duu / (2 l)
        c_ac = c_au = c_cu = c_acu = 0.0
        if full:                                         # + gain dphi, phi = atan2(y, x)
            h = k[GAIN] / (x * x + y * y)
            hy, hxl = h * y, h * x / l
            c_ac, c_au, c_cu, c_acu = -hy * uu, hy * cu, hy * au, hxl * uu
            c_uu += 0.5 * hxl * acu - hy * ac
        for r in range(3):                               # translation: du = e_r
            J[i, r] = c_au * k[A + r] + 2.0 * c_uu * w[U + r] + c_cu * w[RC + r] + c_acu * w[AXRC + r]
        for j in range(3):                               # angle j: du = dR_j m, drc = dR_j c
            D = dR[j]
            dm0, dm1, dm2 = _rotate(D, k, M)
            dc0, dc1, dc2 = _rotate(D, k, C)
            u0, u1, u2 = w[U], w[U + 1], w[U + 2]
            a0, a1, a2 = k[A], k[A + 1], k[A + 2]
            dac = a0 * dc0 + a1 * dc1 + a2 * dc2
            dau = a0 * dm0 + a1 * dm1 + a2 * dm2
            duu = 2.0 * (u0 * dm0 + u1 * dm1 + u2 * dm2)
            dcu = dc0 * u0 + dc1 * u1 + dc2 * u2 + w[RC] * dm0 + w[RC + 1] * dm1 + w[RC + 2] * dm2
            dacu = ((a1 * dc2 - a2 * dc1) * u0 + (a2 * dc0 - a0 * dc2) * u1 + (a0 * dc1 - a1 * dc0) * u2
                    + w[AXRC] * dm0 + w[AXRC + 1] * dm1 + w[AXRC + 2] * dm2)
            J[i, 3 + j] = c_ac * dac + c_au * dau + c_uu * duu + c_cu * dcu + c_acu * dacu


def _regular(legs):
    """False where the numpy path raises SingularHookeError: sin_b^2 sin_m^2 < SINGULAR_TOL^2, or NaN."""
    for i in range(6):
        w = legs[i]
        if not (w[X] * w[X] + w[Y] * w[Y]) / (w[UU] * w[UU]) >= SINGULAR_TOL ** 2:
            return False
    return True


def _lu_factor(F, piv):
    """In-place LU with partial pivoting, LAPACK getrf layout (0-based piv); False on a zero pivot."""
    for k in range(6):
        best, big = k, abs(F[k, k])
        for i in range(k + 1, 6):
            if abs(F[i, k]) > big:
                best, big = i, abs(F[i, k])
        piv[k] = best
        if big == 0.0:
            return False
        if best != k:
            for j in range(6):
                F[k, j], F[best, j] = F[best, j], F[k, j]
        inv = 1.0 / F[k, k]
        for i in range(k + 1, 6):
            f = F[i, k] * inv
            F[i, k] = f
            for j in range(k + 1, 6):
                F[i, j] -= f * F[k, j]
    return True


def _lu_solve(F, piv, b, x):
    """x = F^-1 b from `_lu_factor` (or LAPACK getrf) output."""
    for i in range(6):
        x[i] = b[i]
    for k in range(6):
        if piv[k] != k:
            x[k], x[piv[k]] = x[piv[k]], x[k]
    for i in range(6):
        for j in range(i):
            x[i] -= F[i, j] * x[j]
    for i in range(5, -1, -1):
        for j in range(i + 1, 6):
            x[i] -= F[i, j] * x[j]
        x[i] /= F[i, i]


def _condition_bound(J, lu, piv):
    """|J|_F |J^-1|_F >= cond_2(J), the numpy path's cheap test before np.linalg.cond."""
    unit, col = np.empty(6), np.empty(6)
    inv2, j2 = 0.0, 0.0
    for j in range(6):
        for i in range(6):
            unit[i] = 1.0 if i == j else 0.0
            j2 += J[i, j] * J[i, j]
        _lu_solve(lu, piv, unit, col)
        for i in range(6):
            inv2 += col[i] * col[i]
    return math.sqrt(j2 * inv2)


def _newton(L, p, cold, consts, home, home_piv, curvature, euler, compensate, full, tol, max_iter, want_bound,
            hist):
    """SinglePoseFK.solve on p (6,) in place. Returns (status, iterations, residual, len(history),
    condition bound); the residual history goes to hist."""
    legs, e, step = np.empty((6, 18)), np.empty(6), np.empty(6)
    J, lu, piv = np.empty((6, 6)), np.empty((6, 6)), np.zeros(6, dtype=np.int64)
    n, iterations, k, have_J, res = 0, 0, 0, False, 0.0
    if cold:
        # residual at p0 is L - l(p0) (theta(p0) = 0); the first step and its matrix are known
        res = 0.0
        for i in range(6):
            e[i] = L[i] - consts[i, L0]
            res = max(res, abs(e[i]))
        hist[0] = res
        n = 1
        if res < tol:
            return OK, 0, res, n, 0.0
        if max_iter == 0:
            return NOT_CONVERGED, 0, res, n, 0.0
        for i in range(6):            # second-order home step (home_step.py): d1 = A e, d = d1 - C[d1, d1]
            s = 0.0
            for j in range(6):
                s += home[2, i, j] * e[j]
            step[i] = s
        for i in range(6):
            corr = 0.0
            for j in range(6):
                r = 0.0
                for k in range(6):
                    r += curvature[6 * i + j, k] * step[k]
                corr += r * step[j]
            p[i] += step[i] - corr
        for i in range(6):
            piv[i] = home_piv[i]
            for j in range(6):
                J[i, j], lu[i, j] = home[0, i, j], home[1, i, j]
        have_J, iterations, k = True, 1, 1
    while True:
        R, dRa, dRb, dRg = _rotation(euler, p[3], p[4], p[5])
        _evaluate(p, L, consts, R, compensate, legs, e)
        res, total = 0.0, 0.0
        for i in range(6):
            res = max(res, abs(e[i]))
            total += e[i]
        if n == hist.size:
            return HISTORY_FULL, iterations, res, n, 0.0
        hist[n] = res
        n += 1
        if res < tol and math.isfinite(total):
            if not _regular(legs):
                return SINGULAR_HOOKE, iterations, res, n, 0.0
            if have_J:               # chord step with the last matrix: pose error to round-off
                _lu_solve(lu, piv, e, step)
                for i in range(6):
                    p[i] += step[i]
            break
        if k == max_iter:
            return NOT_CONVERGED, iterations, res, n, 0.0
        _jacobian(legs, consts, (dRa, dRb, dRg), full, J)
        for i in range(6):
            for j in range(6):
                lu[i, j] = J[i, j]
        if not _lu_factor(lu, piv):
            return SINGULAR_JACOBIAN, iterations, res, n, 0.0
        _lu_solve(lu, piv, e, step)
        total = 0.0
        for i in range(6):
            total += step[i]
        if not math.isfinite(total):
            return SINGULAR_JACOBIAN, iterations, res, n, 0.0
        for i in range(6):
            p[i] += step[i]
        have_J = True
        iterations += 1
        k += 1
    bound = _condition_bound(J, lu, piv) if want_bound and iterations > 0 else 0.0
    return OK, iterations, res, n, bound


_KERNEL = ("rotation_zyx", "rotation_xyz", "_rotation", "_rotate", "_evaluate", "_jacobian", "_regular", "_lu_factor", "_lu_solve",
           "_condition_bound", "_newton")


def _compile():
    """jit the kernel functions in place on first use (robocal.model.kernel_jit: cache=True keeps the machine code
    in __pycache__, so later processes skip the compilation)."""
    jit_in_place(globals(), _KERNEL)
