"""Log-Cholesky parametrisation of a rigid body's inertial parameters (Rucker & Wensing 2022).

theta = [alpha, d1, d2, d3, s12, s23, s13, t1, t2, t3] (10 free reals) gives
    U = exp(alpha) [[e^d1, s12, s13, t1], [0, e^d2, s23, t2], [0, 0, e^d3, t3], [0, 0, 0, 1]]
and the pseudo-inertia J = U U^T, positive definite for every theta: any theta is a physically
realisable body, and every non-degenerate body has exactly one theta. The 10 inertial parameters
(inertial.py order) are linear in J. See docs/dynamics_tiago.md.
"""
from __future__ import annotations

import numpy as np

from robocal.dynamics.inertial import params_from_pseudo_inertia, pseudo_inertia
from robocal.errors import InputError

#: (row, column) of U for theta[4:10]
OFF_DIAGONAL = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))
#: flips the index order: turns a lower Cholesky factor into the upper one this map uses
_FLIP = np.eye(4)[::-1]


def factor(theta: np.ndarray) -> np.ndarray:
    """U (4, 4) of one body's theta (10,)."""
    alpha, d = theta[0], theta[1:4]
    V = np.zeros((4, 4))
    V[np.arange(3), np.arange(3)] = np.exp(d)
    V[3, 3] = 1.0
    for (r, c), s in zip(OFF_DIAGONAL, theta[4:]):
        V[r, c] = s
    return np.exp(alpha) * V


def params_of(theta: np.ndarray) -> np.ndarray:
    """The 10 inertial parameters of one body from its theta."""
    U = factor(theta)
    return params_from_pseudo_inertia(U @ U.T)


def theta_of(params10: np.ndarray, floor: float = 1e-6) -> np.ndarray:
    """theta of a body. A pseudo-inertia that is not positive definite (a degenerate or unphysical
    body, which has no finite theta) is first projected: its eigenvalues are raised to at least
    `floor` x its trace (the nearest consistent body in the Frobenius norm, up to that floor)."""
    J = pseudo_inertia(np.asarray(params10, float))
    trace = np.trace(J)
    if not trace > 0:
        raise InputError("a body's pseudo-inertia has no positive trace: no mass to start from", field="inertial")
    eig, vec = np.linalg.eigh(J)
    if eig[0] < floor * trace:
        J = (vec * np.maximum(eig, floor * trace)) @ vec.T
    U = _FLIP @ np.linalg.cholesky(_FLIP @ J @ _FLIP) @ _FLIP
    scale = U[3, 3]
    V = U / scale
    return np.r_[np.log(scale), np.log(np.diag(V)[:3]), [V[r, c] for r, c in OFF_DIAGONAL]]


def params_jacobian(theta: np.ndarray) -> np.ndarray:
    """d params / d theta (10, 10) of one body (analytic: dJ = dU U^T + U dU^T)."""
    U = factor(theta)
    e = np.exp(theta[0])
    out = np.empty((10, 10))
    for k in range(10):
        dU = np.zeros((4, 4))
        if k == 0:
            dU = U
        elif k < 4:
            dU[k - 1, k - 1] = e * np.exp(theta[k])
        else:
            dU[OFF_DIAGONAL[k - 4]] = e
        out[:, k] = params_from_pseudo_inertia(dU @ U.T + U @ dU.T)
    return out


def stacked_params(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parameters (10 nb,) of nb bodies' stacked theta and the block-diagonal Jacobian (10 nb, 10 nb)."""
    nb = len(theta) // 10
    params = np.empty(10 * nb)
    jac = np.zeros((10 * nb, 10 * nb))
    for b in range(nb):
        sl = slice(10 * b, 10 * b + 10)
        params[sl] = params_of(theta[sl])
        jac[sl, sl] = params_jacobian(theta[sl])
    return params, jac
