"""Closed-form inverse kinematics with nut-rotation compensation, its Jacobian, and Newton FK.

Per strut i, at pose p (docs/floating_nut_hexapod.md, signed atan2 form):
  u_i   = t + R m_i - b_i,   l_i = |u_i|,   s_i = u_i / l_i           effective length (eq. 1)
  n_b   = a_i x u_i,   n_m = (R c_i) x u_i                          Hooke-plane normals
  phi_i = atan2((n_b x n_m).s_i, n_b.n_m)                           housing-to-rod roll angle
  theta_i = wrap(phi_i(p) - phi_i(p0))                              nut rotation (eq. 2')
  l_a,i = sigma_i L_i theta_i / (2 pi)                              additional length (eq. 4')
  l_c,i = l_i + l_a,i                                               motor command length (eq. 5)
With the patent's radial axes (a_i = b_i/|b_i|, c_i = m_i/|m_i|) n_b, n_m are its r x u normals.

Everything is vectorised over poses (leading axis N) and legs (6); a single pose (6,) gives (6,).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from robocal.errors import InputError
from robocal.systems.floating_nut.batch_fk import newton_batch
from robocal.systems.floating_nut.fk_compiled import single_pose_solver
from robocal.systems.floating_nut.home_step import HomeStep
from robocal.systems.floating_nut.geometry import N_LEGS, FloatingNutGeometry, omega_maps, rotation_matrices
from robocal.systems.floating_nut.inputs import as_lengths, as_poses, single_pose_inputs
from robocal.systems.floating_nut.results import (SINGULAR_TOL, TWO_PI, FKResult, IKDetails,
                                                  SingularHookeError, wrap_angle)
from robocal.systems.floating_nut.vectors import cross, dot, universal_angles

log = logging.getLogger(__name__)

JACOBIAN_MODES = ("full", "uncompensated", "fd")

@dataclass
class _PoseTerms:
    """Per-pose, per-leg intermediate values (arrays (N, 6) or (N, 6, 3))."""
    R: np.ndarray        # (N, 3, 3)
    rm: np.ndarray       # R m_i, O_m -> M_i in base components
    u: np.ndarray        # B_i -> M_i
    length: np.ndarray   # l_i
    s: np.ndarray        # unit strut axis
    c: np.ndarray        # R c_i, platform Hooke axis in base components
    nb: np.ndarray       # a_i x u_i
    nm: np.ndarray       # c x u_i
    x: np.ndarray        # nb . nm
    y: np.ndarray        # (nb x nm) . s
    phi: np.ndarray      # atan2(y, x)


class FloatingNutKinematics:
    """Closed-form kinematics of one `FloatingNutGeometry` (home values cached at construction).

    use_numba: single-pose FK in the numba kernel (floating_nut_fk_compiled.py). None: when numba
    imports and ROBOCAL_NO_NUMBA is not set to 1; False: numpy only; True: numba required."""

    def __init__(self, geometry: FloatingNutGeometry, use_numba: bool | None = None):
        self.geometry = geometry
        g = geometry
        self._b, self._m, self._a, self._c = g.b, g.m, g.base_axes, g.plat_axes
        self._gain = g.sigma * g.lead / TWO_PI          # l_a = gain * theta
        self._phi0 = np.zeros(N_LEGS)
        home = self._terms(g.p0[None], what="home pose p0")
        self._phi0 = home.phi[0]
        self._l0 = home.length[0]
        self._s0 = home.s[0]
        self._s0_plat = home.s[0] @ home.R[0]             # R0^T s0, home strut axis in {O_m}
        self._single = None                               # single-pose FK tables, see fk
        self._home_step = None                            # second-order first FK step, see home_step
        self._use_numba = use_numba

    # ---- home values ------------------------------------------------------------------
    @property
    def home_lengths(self) -> np.ndarray:
        """l_i(p0) = l_c,i(p0), (6,) m."""
        return self._l0.copy()

    @property
    def home_dihedral(self) -> np.ndarray:
        """phi_i(p0), (6,) rad."""
        return self._phi0.copy()

    # ---- core terms -------------------------------------------------------------------
    def _terms(self, P: np.ndarray, what: str = "pose") -> _PoseTerms:
        R = rotation_matrices(P[:, 3:], self.geometry.euler)
        Rt = R.transpose(0, 2, 1)
        rm = self._m @ Rt                                  # (N, 6, 3)
        u = P[:, None, :3] + rm - self._b
        length = np.sqrt(dot(u, u))
        s = u / length[..., None]
        c = self._c @ Rt
        nb, nm = cross(self._a, u), cross(c, u)
        self._check_singular(nb, nm, length, what)
        x = dot(nb, nm)
        y = dot(cross(nb, nm), s)
        return _PoseTerms(R, rm, u, length, s, c, nb, nm, x, y, np.arctan2(y, x))

    @staticmethod
    def _check_singular(nb, nm, length, what):
        # |a x s| and |c x s|: both axes are unit, so these are sines of the axis-strut angles
        l2 = length * length
        sin_b = dot(nb, nb) / l2        # squared sines
        sin_m = dot(nm, nm) / l2
        tol = SINGULAR_TOL ** 2
        bad = (sin_b < tol) | (sin_m < tol) | ~np.isfinite(sin_b + sin_m)
        if np.any(bad):
            n, leg = (int(v) for v in np.argwhere(bad)[0])
            side = "base" if not sin_b[n, leg] >= tol else "platform"
            raise SingularHookeError(
                f"{what} {n}: the {side} Hooke axis of leg {leg + 1} is parallel to the strut "
                f"(|axis x s| < {SINGULAR_TOL:g}); the nut rotation is undefined there", sample=n, leg=leg)

    # ---- inverse kinematics -------------------------------------------------------------
    def effective_lengths(self, poses) -> np.ndarray:
        """Distance between Hooke centres l_i(p): (N, 6) or (6,), m (eq. 1)."""
        P, single = as_poses(poses)
        R = rotation_matrices(P[:, 3:], self.geometry.euler)
        u = P[:, None, :3] + self._m @ R.transpose(0, 2, 1) - self._b
        out = np.sqrt(dot(u, u))
        return out[0] if single else out

    def dihedral(self, poses) -> np.ndarray:
        """Signed angle phi_i from plane (a_i, u_i) to plane (R c_i, u_i) about s_i, rad."""
        P, single = as_poses(poses)
        phi = self._terms(P).phi
        return phi[0] if single else phi

    def nut_rotation(self, poses, patent_unsigned: bool = False) -> np.ndarray:
        """Nut rotation theta_i relative to the screw since p0, rad: (N, 6) or (6,).

        patent_unsigned=True gives the patent's eq. (2), arccos(p) - arccos(p0), without its lost
        direction rule; it has the wrong sign on legs whose home dihedral is negative (comparison only).
        """
        P, single = as_poses(poses)
        t = self._terms(P)
        if patent_unsigned:
            x0 = np.cos(self._phi0)
            cos_p = t.x / np.sqrt(dot(t.nb, t.nb) * dot(t.nm, t.nm))
            theta = np.arccos(np.clip(cos_p, -1, 1)) - np.arccos(np.clip(x0, -1, 1))
        else:
            theta = wrap_angle(t.phi - self._phi0)
        return theta[0] if single else theta

    def additional_lengths(self, poses) -> np.ndarray:
        """l_a,i = sigma_i L_i theta_i / (2 pi): (N, 6) or (6,), m (eq. 4')."""
        return self._gain * self.nut_rotation(poses)

    def ik(self, poses, compensate: bool = True, return_details: bool = False):
        """Motor command lengths l_c = l + l_a (eq. 5), (N, 6) or (6,) m.

        compensate=False gives the classic 6-UPS lengths l. With return_details an `IKDetails`
        is returned as well (Hooke angles included).
        """
        P, single = as_poses(poses)
        t = self._terms(P)
        theta = wrap_angle(t.phi - self._phi0)
        additional = self._gain * theta
        command = t.length + additional if compensate else t.length.copy()
        out = command[0] if single else command
        if not return_details:
            return out
        details = IKDetails(t.length, theta, additional, command, t.phi, self._hooke_from_terms(t))
        if single:
            details = IKDetails(*(getattr(details, k)[0] for k in details.__dataclass_fields__))
        return out, details

    # ---- Jacobian ---------------------------------------------------------------------
    def _gradients(self, t: _PoseTerms):
        """Gradients of l_i and phi_i with respect to a platform twist (v, omega) in {O_b}.

        Returns (lv, lw, fv, fw), each (N, 6, 3): dl = lv.v + lw.omega, dphi = fv.v + fw.omega.
        Derivation: du = v + omega x Rm, d n_b = a x du, d n_m = (omega x c) x u + c x du,
        dphi = (x dy - y dx)/(x^2 + y^2) with y = (n_b x n_m).s; n_b x n_m is parallel to s, so
        ds drops out and dphi = d n_b.G + d n_m.H with G, H below; then move du, omega out.
        """
        r2 = (t.x * t.x + t.y * t.y)[..., None]
        x, y = t.x[..., None], t.y[..., None]
        G = (x * cross(t.nm, t.s) - y * t.nm) / r2
        H = (x * cross(t.s, t.nb) - y * t.nb) / r2
        W = cross(G, self._a) + cross(H, t.c)              # coefficient of du
        fw = cross(t.rm, W) + cross(t.c, cross(t.u, H))
        return t.s, cross(t.rm, t.s), W, fw

    def _pose_rows(self, gv, gw, P):
        """Rows d(.)/dp (N, 6, 6) from twist gradients: omega = T(angles) @ angle rates."""
        T = omega_maps(P[:, 3:], self.geometry.euler)
        return np.concatenate([gv, gw @ T], axis=2)

    def _rates(self, t: _PoseTerms, P):
        """dl/dp and dphi/dp, each (N, 6 legs, 6 pose coordinates)."""
        lv, lw, fv, fw = self._gradients(t)
        return self._pose_rows(lv, lw, P), self._pose_rows(fv, fw, P)

    def jacobian(self, poses, compensate: bool = True, mode: str = "analytic") -> np.ndarray:
        """J_c = d l_c / d p, (N, 6, 6) or (6, 6): rows legs, columns [x y z alpha beta gamma].

        mode "analytic" or "fd" (central differences, step 1e-6, for checks).
        """
        P, single = as_poses(poses)
        if mode == "fd":
            J = self._fd_jacobian(P, compensate)
        elif mode == "analytic":
            J = self._newton_matrix(self._terms(P), P, compensate, "full")
        else:
            raise InputError(f"jacobian mode must be 'analytic' or 'fd', got '{mode}'", field="mode")
        return J[0] if single else J

    def length_and_roll_jacobians(self, poses) -> tuple[np.ndarray, np.ndarray]:
        """J_l = dl/dp and J_theta = dtheta/dp separately, each (N, 6, 6) or (6, 6)."""
        P, single = as_poses(poses)
        dl, dphi = self._rates(self._terms(P), P)
        return (dl[0], dphi[0]) if single else (dl, dphi)

    def _fd_jacobian(self, P, compensate, h=1e-6):
        J = np.empty((P.shape[0], N_LEGS, 6))
        for k in range(6):
            dp = np.zeros(6)
            dp[k] = h
            J[:, :, k] = (self.ik(P + dp, compensate) - self.ik(P - dp, compensate)) / (2 * h)
        return J

    # ---- derivatives for calibration --------------------------------------------------------
    def lead_derivative(self, poses) -> np.ndarray:
        """d l_c,i / d L_i (leg i's own lead; other legs' leads do not enter): (N, 6) or (6,), m/m."""
        return self.geometry.sigma / TWO_PI * self.nut_rotation(poses)

    def axis_derivatives(self, poses) -> tuple[np.ndarray, np.ndarray]:
        """Derivatives of l_c,i with respect to small rotations of leg i's Hooke axes.

        The base axis moves as a_i -> a_i + delta x a_i with delta (3,) in {O_b}; the platform axis
        as c_i -> c_i + delta x c_i with delta in {O_m}. The home dihedral phi_i(p0) moves too and
        is included. Components along the axis itself are zero; project on `tangent_basis` for the
        two angles of each axis. Returns (base, plat), each (N, 6, 3) or (6, 3), m/rad.
        """
        P, single = as_poses(poses)
        g = self.geometry
        base, plat = self._dphi_daxes(P)
        base0, plat0 = self._dphi_daxes(g.p0[None])
        scale = self._gain[:, None]
        base, plat = scale * (base - base0), scale * (plat - plat0)
        return (base[0], plat[0]) if single else (base, plat)

    def _dphi_daxes(self, P):
        t = self._terms(P)
        eye = np.eye(3)
        da = cross(eye[:, None], self._a)                    # (3, 6, 3): d a_i for delta = e_j
        dc_plat = cross(eye[:, None], self._c)               # (3, 6, 3), in {O_m}
        dc = dc_plat[None] @ t.R.transpose(0, 2, 1)[:, None]  # (N, 3, 6, 3) in {O_b}
        u = t.u[:, None]
        dnb = cross(da[None], u)
        dnm = cross(dc, u)
        A = cross(t.nm, t.s)[:, None]
        B = cross(t.s, t.nb)[:, None]
        x, y = t.x[:, None], t.y[:, None]
        r2 = x * x + y * y
        d_base = (x * dot(dnb, A) - y * dot(dnb, t.nm[:, None])) / r2
        d_plat = (x * dot(dnm, B) - y * dot(t.nb[:, None], dnm)) / r2
        return d_base.transpose(0, 2, 1), d_plat.transpose(0, 2, 1)

    # ---- Hooke joint angles -----------------------------------------------------------------
    def hooke_angles(self, poses) -> np.ndarray:
        """Hooke angles (N, 6, 4) or (6, 4), rad: q1 about a_i, q2 about the housing axis (base
        joint), q5 about the rod axis, q6 about c_i (platform joint, measured platform -> rod)."""
        P, single = as_poses(poses)
        out = self._hooke_from_terms(self._terms(P))
        return out[0] if single else out

    def _hooke_from_terms(self, t: _PoseTerms) -> np.ndarray:
        s_plat = np.einsum("nji,nlj->nli", t.R, t.s)        # R^T s
        q1, q2 = universal_angles(self._a, self._s0, t.s)
        q6, q5 = universal_angles(self._c, self._s0_plat, s_plat)
        return np.stack([q1, q2, q5, q6], axis=-1)

    # ---- forward kinematics -------------------------------------------------------------------
    def fk(self, lengths, p_init=None, compensate: bool = True, jacobian: str = "full",
           tol: float = 1e-12, max_iter: int = 50, warn_condition: float | None = 1e8) -> FKResult:
        """Platform pose from motor command lengths by Newton on l_c(p) = lengths.

        lengths (6,) or (N, 6) m; p_init (6,) or (N, 6) start pose (default p0; pass the previous
        solution when tracking). compensate=False solves the classic 6-UPS model l(p) = lengths.
        jacobian: "full" (exact J_c), "uncompensated" (J_l only: quasi-Newton) or "fd".
        Stops when |residual|_inf < tol (m), then takes one chord step with the last matrix (no new
        kinematics), so the pose error is at round-off rather than |J^-1| tol. `iterations` counts
        Newton updates with a fresh matrix. Raises FKNotConverged (naming the sample) otherwise;
        logs a warning when cond(J) near the solution exceeds warn_condition.
        One pose with an analytic matrix goes to a lean solver with the same iterates (floating_nut_fk.py,
        or its numba kernel, see the class docstring).
        """
        if jacobian not in JACOBIAN_MODES:
            raise InputError(f"jacobian must be one of {JACOBIAN_MODES}, got '{jacobian}'", field="jacobian")
        # every solver counts iterations up to max_iter: no limit would let a diverging Newton run forever
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 0:
            raise InputError(f"max_iter must be an integer >= 0, got {max_iter!r}", field="max_iter")
        if not tol > 0.0:
            raise InputError(f"tol must be a positive number of metres, got {tol!r}", field="tol")
        lean = None if jacobian == "fd" else single_pose_inputs(lengths, p_init)
        if lean is not None:
            return self._single_pose_solver().solve(*lean, compensate, jacobian, tol, max_iter, warn_condition)
        L, single = as_lengths(lengths)
        P = np.array(np.broadcast_to(self.geometry.p0 if p_init is None else p_init, L.shape), dtype=float)
        as_poses(P)
        P, iterations, residual, history = newton_batch(self, L, P, p_init is None, compensate, jacobian, tol,
                                                        max_iter, warn_condition)
        if single:
            return FKResult(P[0], int(iterations[0]), float(residual[0]), history)
        return FKResult(P, iterations, residual, history)

    def home_step(self) -> HomeStep:
        """The second-order first step of every cold FK solve (home_step.py), built on first use."""
        if self._home_step is None:
            self._home_step = HomeStep(self)
        return self._home_step

    def _single_pose_solver(self):
        """The lean single-pose FK of this geometry (numba or numpy), built on first use."""
        if self._single is None:
            self._single = single_pose_solver(self, self._use_numba)
        return self._single

    def _newton_matrix(self, t, P, compensate, jacobian):
        if jacobian == "fd":
            return self._fd_jacobian(P, compensate)
        lv, lw, fv, fw = self._gradients(t)
        if compensate and jacobian == "full":
            k = self._gain[:, None]
            return self._pose_rows(lv + k * fv, lw + k * fw, P)
        return self._pose_rows(lv, lw, P)

    # ---- motor maps ---------------------------------------------------------------------------
    def motor_to_lengths(self, psi, psi0=0.0) -> np.ndarray:
        """Command lengths from motor angles (rad): l_c = l_c(p0) + L (psi - psi0) / (2 pi gear).

        The motor angle is counted positive in the direction that lengthens the command.
        """
        psi = np.asarray(psi, dtype=float)
        g = self.geometry
        return self._l0 + g.lead * (psi - psi0) / (TWO_PI * g.gear_ratio)

    def lengths_to_motor(self, lengths, psi0=0.0) -> np.ndarray:
        """Motor angles (rad) that command the given lengths (inverse of `motor_to_lengths`)."""
        g = self.geometry
        if np.any(g.lead == 0):
            raise InputError("a zero lead cannot be converted to motor angles", field="lead")
        return psi0 + (np.asarray(lengths, dtype=float) - self._l0) * TWO_PI * g.gear_ratio / g.lead
