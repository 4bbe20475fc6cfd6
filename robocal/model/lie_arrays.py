"""SO(3)/SE(3) operations on stacks of matrices (n, 3, 3), as whole-array numpy.

The batched residuals need Pinocchio's log3 and Jlog3 for thousands of rotations at once; calling
`pin.log3` per sample costs more than the rest of the pass. These follow Pinocchio 4.1's own formulas
(src/spatial/log.hxx: renormalise, acos of the trace, theta/sin(theta) with its Taylor branch) so the
two agree to rounding; rotations within sqrt(eps) of a half turn, where Pinocchio switches to its
singular branch, are handed to `pin.log3` itself, one by one (they are rare).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

EPS = np.finfo(float).eps
TAYLOR_2 = EPS ** (1.0 / 3.0)     # Pinocchio's TaylorSeriesExpansion precision<2>
TAYLOR_3 = EPS ** (1.0 / 4.0)     # precision<3>


def skew(v: np.ndarray) -> np.ndarray:
    """(n, 3, 3) cross-product matrices of (n, 3) vectors."""
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def transpose(R: np.ndarray) -> np.ndarray:
    return np.swapaxes(R, -1, -2)


def cross(a: np.ndarray, b: np.ndarray, axis: int = -1, out: np.ndarray | None = None) -> np.ndarray:
    """a x b along `axis` (np.cross without its axis juggling, which dominates on small stacks); the components
    are views and the products are written into the result (no copies of strided inputs), or into `out`."""
    def at(i):
        return (Ellipsis, i) + (slice(None),) * (-axis - 1) if axis < 0 else (slice(None),) * axis + (i,)
    a0, a1, a2 = a[at(0)], a[at(1)], a[at(2)]
    b0, b1, b2 = b[at(0)], b[at(1)], b[at(2)]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape)) if out is None else out
    for i, (x, y, u, v) in enumerate(((a1, b2, a2, b1), (a2, b0, a0, b2), (a0, b1, a1, b0))):
        np.multiply(x, y, out=out[at(i)])
        out[at(i)] -= u * v
    return out


def _renormalised_entries(R: np.ndarray):
    """What log3 reads of the stack after Pinocchio's renormalize_rotation_matrix (c0, c1 normalised,
    c2 = c0 x c1, c0 = c1 x c2): its trace and antisymmetric part, worked on (n,) component vectors, which on
    small stacks costs a fraction of (n, 3, 3) array operations."""
    x0, y0, z0 = R[:, 0, 0], R[:, 1, 0], R[:, 2, 0]
    x1, y1, z1 = R[:, 0, 1], R[:, 1, 1], R[:, 2, 1]
    n0 = np.sqrt(x0 * x0 + y0 * y0 + z0 * z0)
    n1 = np.sqrt(x1 * x1 + y1 * y1 + z1 * z1)
    x0, y0, z0 = x0 / n0, y0 / n0, z0 / n0
    x1, y1, z1 = x1 / n1, y1 / n1, z1 / n1
    x2, y2, z2 = y0 * z1 - z0 * y1, z0 * x1 - x0 * z1, x0 * y1 - y0 * x1     # column 2 = c0 x c1
    u0, v0, t0 = y1 * z2 - z1 * y2, z1 * x2 - x1 * z2, x1 * y2 - y1 * x2     # column 0 = c1 x c2
    trace = u0 + y1 + z2
    anti = np.empty((len(R), 3))
    anti[:, 0] = z1 - y2          # R21 - R12
    anti[:, 1] = x2 - t0          # R02 - R20
    anti[:, 2] = v0 - x1          # R10 - R01
    anti *= 0.5
    return trace, anti


def log3(R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(log (n, 3), theta (n,)) of a stack of rotations, as pin.log3."""
    tr, anti = _renormalised_entries(R)
    cos_value = (tr - 1.0) / 2.0
    expansion = np.sqrt(2.0 * (1.0 - cos_value) + EPS * EPS)
    theta = np.where(tr <= 3.0 - TAYLOR_2, np.arccos(np.clip(cos_value, -1.0, 1.0)), expansion)
    a2 = np.einsum("...i,...i->...", anti, anti)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = theta / np.sin(theta)
    t = np.where(theta >= TAYLOR_2, ratio, 1.0 + a2 / 6.0 + a2 * a2 * 3.0 / 40.0)
    w = anti
    w *= t[:, None]
    for i in np.flatnonzero(cos_value < -1.0 + TAYLOR_2):   # near a half turn: Pinocchio's singular branch
        w[i] = pin.log3(np.ascontiguousarray(R[i]))
        theta[i] = np.linalg.norm(w[i])
    return w, theta


def jlog3(w: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """(n, 3, 3) Jlog3 from log3's output, as pin.Jlog3."""
    st, ct = np.sin(theta), np.cos(theta)
    with np.errstate(divide="ignore", invalid="ignore"):
        st_1mct = st / (1.0 - ct)
        alpha = np.where(theta < TAYLOR_3, 1.0 / 12.0 + theta * theta / 720.0,
                         1.0 / (theta * theta) - st_1mct / (2.0 * theta))
        diag = np.where(theta < TAYLOR_3, 0.5 * (2.0 - theta * theta / 6.0), 0.5 * (theta * st_1mct))
    J = w[:, :, None] * (alpha[:, None] * w)[:, None, :]       # alpha w w^T
    flat = J.reshape(len(J), 9)
    flat[:, ::4] += diag[:, None]
    h = 0.5 * w
    flat[:, 1] -= h[:, 2]
    flat[:, 2] += h[:, 1]
    flat[:, 3] += h[:, 2]
    flat[:, 5] -= h[:, 0]
    flat[:, 6] -= h[:, 1]
    flat[:, 7] += h[:, 0]
    return J


def act(R: np.ndarray, p: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(n, 3) points x (3,) or (n, 3) moved by the poses (R, p)."""
    return np.einsum("nij,...j->ni", R, x) + p if x.ndim == 1 else np.einsum("nij,nj->ni", R, x) + p


def point_jacobian(R: np.ndarray, x_local: np.ndarray) -> np.ndarray:
    """(n, 3, 6) derivative of the world point M x_local w.r.t. a LOCAL right twist of each M."""
    n = len(R)
    out = np.empty((n, 3, 6))
    out[:, :, :3] = R
    out[:, :, 3:] = -R @ skew(np.broadcast_to(x_local, (n, 3)))
    return out


def adjoint(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(..., 6, 6) action matrices of the poses (R, p), twist order [v; w]."""
    out = np.zeros(R.shape[:-2] + (6, 6))
    out[..., :3, :3] = R
    out[..., 3:, 3:] = R
    out[..., :3, 3:] = skew(p) @ R
    return out


def adjoint_inverse(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(n, 6, 6) action matrices of the inverses of the poses (R, p) (Pinocchio's twist order v, w)."""
    Rt = transpose(R)
    out = np.zeros(R.shape[:-2] + (6, 6))
    out[..., :3, :3] = Rt
    out[..., 3:, 3:] = Rt
    out[..., :3, 3:] = -Rt @ skew(p)      # [-R^T p]x R^T = -R^T [p]x
    return out


def quaternions(R: np.ndarray) -> np.ndarray:
    """(n, 4) unit quaternions (x, y, z, w) of a stack of rotations, by the branch rule of Eigen's
    Quaternion(R) (Pinocchio's pin.Quaternion), so signs agree with it."""
    R = np.asarray(R, float)
    n = len(R)
    q = np.empty((n, 4))
    tr = np.trace(R, axis1=-2, axis2=-1)
    pos = tr > 0
    t = np.sqrt(tr[pos] + 1.0)
    h = 0.5 / t
    Rp = R[pos]
    q[pos] = np.column_stack([(Rp[:, 2, 1] - Rp[:, 1, 2]) * h, (Rp[:, 0, 2] - Rp[:, 2, 0]) * h,
                              (Rp[:, 1, 0] - Rp[:, 0, 1]) * h, 0.5 * t])
    d = np.diagonal(R, axis1=-2, axis2=-1)
    i = np.where(d[:, 1] > d[:, 0], 1, 0)
    i = np.where(d[:, 2] > d[np.arange(n), i], 2, i)
    for k in range(3):                   # the largest diagonal entry's axis leads, as in Eigen
        rows = np.flatnonzero(~pos & (i == k))
        if len(rows) == 0:
            continue
        j, m = (k + 1) % 3, (k + 2) % 3
        Rk = R[rows]
        t = np.sqrt(Rk[:, k, k] - Rk[:, j, j] - Rk[:, m, m] + 1.0)
        h = 0.5 / t
        q[rows, k] = 0.5 * t
        q[rows, 3] = (Rk[:, m, j] - Rk[:, j, m]) * h
        q[rows, j] = (Rk[:, j, k] + Rk[:, k, j]) * h
        q[rows, m] = (Rk[:, m, k] + Rk[:, k, m]) * h
    return q


def quaternion_matrices(q: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotation matrices of unit quaternions (n, 4), x y z w (Pinocchio's toRotationMatrix)."""
    x, y, z, w = q.T
    out = np.empty((len(q), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
    return out
