"""Closed-form kinematics of the 4-PUU parallel CMM: the engine of the calibration's residual
(docs/pcmm_calibration.md).

Reduced geometry (SI: m, rad), limb i = 0..3 (named limb1..limb4):

    A_i  (3,)  effective column point = a_i + d_i + p0_i e_i: where Hooke joint D_i sits at reading 0
    alpha_i, beta_i  tilts of the prismatic axis, e_i = Rx(alpha_i) Ry(beta_i) z
    b_i  (3,)  platform Hooke joint B_i in the moving frame
    l_i        link length |B_i - D_i|

Loop (1): A_i + p_i e_i + l_i u_i = q + Rz(theta) b_i, with p_i the axis reading and y = [x, y, z, theta].
IK, eq. (2), '+' root (slider above the platform joint): p_i = e.E + sqrt((e.E)^2 - E.E + l^2),
E = q + R b_i - A_i. FK: Newton on IK(y) = p stopped when the step's 2-norm is below `tol`.

The 32 reduced parameters, per limb [A_x, A_y, beta, alpha, b_x, b_y, b_z, l] (A_z stays at its nominal
value: a z-shift of the column is the same as the opposite z-shift of b_i because Rz keeps z), give
J_p = J_q^-1 J_eps with B_i = [u_x, u_y, p u.de/dbeta, p u.de/dalpha, -u^T R, +1] (eq. 3; at zero tilt
p u.de/dbeta = p u_x, p u.de/dalpha = -p u_y; the link-length sign is +1 for dl = l_actual - l_nominal).
Everything is batched over N poses.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from robocal.errors import AssemblyError, InputError

LIMB_FIELDS = ("ax", "ay", "beta", "alpha", "bx", "by", "bz", "l")
N_LIMBS = 4
N_REDUCED = N_LIMBS * len(LIMB_FIELDS)


def reduced_names() -> list[str]:
    """Names of the 32 reduced parameters, limb by limb: limb1.ax ... limb4.l."""
    return [f"limb{i + 1}.{f}" for i in range(N_LIMBS) for f in LIMB_FIELDS]


@dataclass(frozen=True)
class PCMMGeometry:
    """Reduced kinematic parameters of a 4-PUU machine (SI), plus the probe.

    columns (4, 3) A_i; tilts (4, 2) (alpha_i, beta_i); platform_joints (4, 3) b_i; lengths (4,) l_i;
    stylus (3,) tip-centre offset t in the moving frame; tip_radius r_tip; home (4,) FK's default start.
    """

    columns: np.ndarray
    tilts: np.ndarray
    platform_joints: np.ndarray
    lengths: np.ndarray
    stylus: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tip_radius: float = 0.0
    home: np.ndarray = field(default_factory=lambda: np.zeros(4))

    def __post_init__(self):
        for name, shape in (("columns", (4, 3)), ("tilts", (4, 2)), ("platform_joints", (4, 3)),
                            ("lengths", (4,)), ("stylus", (3,)), ("home", (4,))):
            value = np.array(getattr(self, name), dtype=float)
            if value.shape != shape or not np.all(np.isfinite(value)):
                raise InputError(f"PCMM geometry: '{name}' must be {shape} finite numbers, got {value.shape}",
                                 field=name)
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        if np.any(self.lengths <= 0):
            raise InputError("PCMM geometry: link lengths must be positive", field="lengths")
        object.__setattr__(self, "tip_radius", float(self.tip_radius))

    # ---- the 32-vector ----------------------------------------------------------------------
    def reduced_vector(self) -> np.ndarray:
        """(32,) absolute values of the reduced parameters (order of `reduced_names`)."""
        per = np.column_stack([self.columns[:, :2], self.tilts[:, 1], self.tilts[:, 0],
                               self.platform_joints, self.lengths])
        return per.reshape(-1)

    def with_reduced(self, x: np.ndarray) -> "PCMMGeometry":
        """Same machine with the 32 reduced parameters set to x (A_z, stylus, tip radius kept)."""
        x = np.asarray(x, dtype=float).reshape(N_LIMBS, len(LIMB_FIELDS))
        cols = np.column_stack([x[:, :2], self.columns[:, 2]])
        return replace(self, columns=cols, tilts=x[:, [3, 2]], platform_joints=x[:, 4:7], lengths=x[:, 7])

    def perturbed(self, d_eps: np.ndarray) -> "PCMMGeometry":
        """Nominal + reduced correction d_eps (32,)."""
        return self.with_reduced(self.reduced_vector() + np.asarray(d_eps, dtype=float))


def rz(theta) -> np.ndarray:
    """(N, 3, 3) rotations about z for (N,) angles."""
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros(np.shape(theta) + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1], R[..., 2, 2] = c, -s, s, c, 1.0
    return R


def drz(theta) -> np.ndarray:
    """(N, 3, 3) derivative of rz with respect to the angle."""
    c, s = np.cos(theta), np.sin(theta)
    D = np.zeros(np.shape(theta) + (3, 3))
    D[..., 0, 0], D[..., 0, 1], D[..., 1, 0], D[..., 1, 1] = -s, -c, c, -s
    return D


def axis_directions(tilts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """e_i = Rx(alpha) Ry(beta) z (4, 3) and its derivatives de/dalpha, de/dbeta (4, 3) each."""
    al, be = tilts[:, 0], tilts[:, 1]
    e = np.column_stack([np.sin(be), -np.sin(al) * np.cos(be), np.cos(al) * np.cos(be)])
    de_da = np.column_stack([np.zeros(4), -np.cos(al) * np.cos(be), -np.sin(al) * np.cos(be)])
    de_db = np.column_stack([np.cos(be), np.sin(al) * np.sin(be), -np.cos(al) * np.sin(be)])
    return e, de_da, de_db


def _as_poses(Y) -> np.ndarray:
    Y = np.asarray(Y, dtype=float)
    if Y.shape[-1] != 4:
        raise InputError(f"poses must be [x, y, z, theta] rows, got shape {Y.shape}", field="pose")
    return Y.reshape(-1, 4)


def _loop_vectors(geo: PCMMGeometry, Y: np.ndarray):
    """E (N, 4, 3) = q + R b_i - A_i and R (N, 3, 3)."""
    R = rz(Y[:, 3])
    E = Y[:, None, :3] + np.einsum("nab,ib->nia", R, geo.platform_joints) - geo.columns[None]
    return E, R


def inverse_kinematics(geo: PCMMGeometry, Y) -> np.ndarray:
    """Axis readings (N, 4) for platform poses Y (N, 4) = [x, y, z, theta]; AssemblyError if unreachable."""
    Y = _as_poses(Y)
    E, _ = _loop_vectors(geo, Y)
    e = axis_directions(geo.tilts)[0]
    s = np.einsum("nia,ia->ni", E, e)
    disc = s * s - np.einsum("nia,nia->ni", E, E) + geo.lengths ** 2
    if np.any(disc < 0):
        n, i = np.argwhere(disc < 0)[0]
        raise AssemblyError(f"pose {n} ({Y[n]}) is out of reach of limb{i + 1} (negative discriminant)")
    return s + np.sqrt(disc)


def _link_state(geo, Y, rho):
    """u (N, 4, 3) unit link directions, R, e, de/dalpha, de/dbeta, u.e (N, 4)."""
    E, R = _loop_vectors(geo, Y)
    e, de_da, de_db = axis_directions(geo.tilts)
    u = (E - rho[:, :, None] * e[None]) / geo.lengths[None, :, None]
    return u, R, e, de_da, de_db, np.einsum("nia,ia->ni", u, e)


def ik_jacobian(geo: PCMMGeometry, Y, rho=None) -> np.ndarray:
    """(N, 4, 4) J_IK = dp/dy; row i = A_i / (u_i.e_i), A_i = [u_i, u_i.(dR/dtheta) b_i]."""
    Y = _as_poses(Y)
    rho = inverse_kinematics(geo, Y) if rho is None else np.asarray(rho, dtype=float).reshape(-1, 4)
    u, R, e, _, _, ue = _link_state(geo, Y, rho)
    return _rows_A(geo, Y, u) / ue[:, :, None]


def _rows_A(geo, Y, u):
    dRb = np.einsum("nab,ib->nia", drz(Y[:, 3]), geo.platform_joints)
    return np.concatenate([u, np.einsum("nia,nia->ni", u, dRb)[:, :, None]], axis=2)


def forward_kinematics(geo: PCMMGeometry, rho, y0=None, tol: float = 1e-13, max_iter: int = 50):
    """Poses Y (N, 4) from readings rho (N, 4) by Newton, and the iteration count.

    Stops when every sample's step 2-norm is below `tol` (m and rad mixed, as in the source document).
    y0: (4,) or (N, 4) start (default geo.home). AssemblyError when a sample leaves the workspace, J_IK
    turns singular or Newton does not converge in max_iter steps (the message names the sample).
    """
    rho = np.asarray(rho, dtype=float).reshape(-1, 4)
    n = len(rho)
    Y = np.broadcast_to(geo.home if y0 is None else np.asarray(y0, dtype=float), (n, 4)).reshape(n, 4).copy()
    active = np.ones(n, dtype=bool)
    for it in range(1, max_iter + 1):
        idx = np.flatnonzero(active)
        Ya = Y[idx]
        try:
            p = inverse_kinematics(geo, Ya)
        except AssemblyError as exc:
            raise AssemblyError(f"forward kinematics left the workspace at iteration {it}: {exc}") from None
        J = ik_jacobian(geo, Ya, p)
        cond = np.linalg.cond(J)
        if np.any(~np.isfinite(cond) | (cond > 1e12)):
            k = idx[int(np.argmax(np.where(np.isfinite(cond), cond, np.inf)))]
            raise AssemblyError(f"sample {k}: J_IK is singular (parallel singularity) at {Y[k]}")
        step = np.linalg.solve(J, (p - rho[idx])[:, :, None])[:, :, 0]
        Y[idx] -= step
        done = np.linalg.norm(step, axis=1) < tol
        active[idx[done]] = False
        if not active.any():
            return Y, it
    k = int(np.flatnonzero(active)[0])
    raise AssemblyError(f"sample {k}: forward kinematics did not converge in {max_iter} Newton steps "
                        f"(readings {rho[k]})")


def tip_points(geo: PCMMGeometry, Y) -> np.ndarray:
    """Probe tip centres X = q + Rz(theta) t, (N, 3)."""
    Y = _as_poses(Y)
    return Y[:, :3] + np.einsum("nab,b->na", rz(Y[:, 3]), geo.stylus)


def tip_pose_jacobian(geo: PCMMGeometry, Y) -> np.ndarray:
    """(N, 3, 4) T = dX/dy = [I | (dR/dtheta) t]."""
    Y = _as_poses(Y)
    T = np.zeros((len(Y), 3, 4))
    T[:, :, :3] = np.eye(3)
    T[:, :, 3] = np.einsum("nab,b->na", drz(Y[:, 3]), geo.stylus)
    return T


def limb_error_rows(geo: PCMMGeometry, Y, rho):
    """A (N, 4, 4) rows of J_q and B (N, 4, 8) rows of eq. (3), so that A dy = B_i d(eps_i)."""
    Y = _as_poses(Y)
    rho = np.asarray(rho, dtype=float).reshape(-1, 4)
    u, R, e, de_da, de_db, _ = _link_state(geo, Y, rho)
    A = _rows_A(geo, Y, u)
    B = np.empty((len(Y), 4, 8))
    B[:, :, 0] = u[:, :, 0]
    B[:, :, 1] = u[:, :, 1]
    B[:, :, 2] = rho * np.einsum("nia,ia->ni", u, de_db)
    B[:, :, 3] = rho * np.einsum("nia,ia->ni", u, de_da)
    B[:, :, 4:7] = -np.einsum("nia,nab->nib", u, R)
    B[:, :, 7] = 1.0
    return A, B


def pose_error_jacobian(geo: PCMMGeometry, Y, rho) -> np.ndarray:
    """(N, 4, 32) J_p = J_q^-1 J_eps: how the pose for fixed readings moves with the reduced parameters."""
    A, B = limb_error_rows(geo, Y, rho)
    n = len(A)
    Jeps = np.zeros((n, 4, N_REDUCED))
    for i in range(N_LIMBS):
        Jeps[:, i, 8 * i:8 * i + 8] = B[:, i]
    return np.linalg.solve(A, Jeps)


def tip_error_jacobian(geo: PCMMGeometry, Y, rho) -> np.ndarray:
    """(N, 3, 32) T J_p: tip-point sensitivity to the reduced parameters at fixed readings."""
    return np.einsum("nab,nbk->nak", tip_pose_jacobian(geo, Y), pose_error_jacobian(geo, Y, rho))


def tip_reading_jacobian(geo: PCMMGeometry, Y, rho) -> np.ndarray:
    """(N, 3, 4) dX/drho = T J_IK^-1 (how axis-reading noise reaches the tip)."""
    return np.einsum("nab,nbc->nac", tip_pose_jacobian(geo, Y), np.linalg.inv(ik_jacobian(geo, Y, rho)))


def random_workspace_poses(n: int, rng: np.random.Generator, xy: float = 0.15, z=(-0.72, -0.48),
                           theta: float = 0.3) -> np.ndarray:
    """(n, 4) poses uniform in the spec's validation box (x, y in +-xy, z in z, theta in +-theta)."""
    return np.column_stack([rng.uniform(-xy, xy, n), rng.uniform(-xy, xy, n), rng.uniform(z[0], z[1], n),
                            rng.uniform(-theta, theta, n)])
