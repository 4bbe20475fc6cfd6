"""Small vector helpers on (..., 3) arrays for the floating-nut kinematics (few numpy calls on small arrays)."""
from __future__ import annotations

import numpy as np

_NEXT, _PREV = np.array([1, 2, 0]), np.array([2, 0, 1])


def cross(a, b):
    if a.size + b.size < 2000:     # small arrays: fewest numpy calls wins
        return a[..., _NEXT] * b[..., _PREV] - a[..., _PREV] * b[..., _NEXT]
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=-1)


def dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def unit(v):
    return v / np.sqrt(dot(v, v))[..., None]


def signed_angle(u, v, k):
    return np.arctan2(dot(cross(u, v), k), dot(u, v))


def rodrigues(k, q, v):
    cq, sq = np.cos(q)[..., None], np.sin(q)[..., None]
    return v * cq + cross(k, v) * sq + k * dot(k, v)[..., None] * (1 - cq)


def universal_angles(axis, s_home, s):
    """Angles of a Hooke joint with fixed axis `axis` (6, 3) carrying a strut from s_home to s.

    First angle about the fixed axis, second about the moving cross axis (docs/floating_nut_hexapod.md).
    """
    a = np.broadcast_to(axis, s.shape)
    cross_home = unit(cross(axis, s_home))
    cross_now = unit(cross(a, s))
    q_first = signed_angle(np.broadcast_to(cross_home, s.shape), cross_now, a)
    s_turned = rodrigues(a, q_first, np.broadcast_to(s_home, s.shape))
    q_second = signed_angle(s_turned, s, cross_now)
    return q_first, q_second
