"""transforms.quat_rotate on large batches in one compiled pass (numba), with the numpy form's
arithmetic element by element, so the same bits: t = 2 cross(q.xyz, v), then
(v + w t) + cross(q.xyz, t), each cross product's component a_i b_j - a_j b_i. The numpy form
makes a dozen passes over strided component views and their temporaries; this makes one.

Imported by transforms on its first large batch (the CLI's option errors come before numba is
imported). The kernel writes into the array it is given and runs on the main thread once
compiled (parallel.compiled_call).

The one-element forms of transforms' functions below (quat_mul1, quat_rotate1, quat_about1,
cross1, normalize1, and np.minimum's and np.maximum's choice) are the arithmetic other kernels
share (baker.locomotion.leg_kernels): quat_mul's sums left to right in the result's columns,
quat_about's [axis sin(h), cos(h)] (a zero axis component times sin(h), not a zero),
normalize's division by max(|v|, eps), np.minimum/np.maximum returning the first argument when
it is smaller, larger or NaN, else the second.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from baker.parallel import compiled_call


def quat_rotate(q: np.ndarray, v: np.ndarray, shape: tuple) -> np.ndarray:
    """(shape + (3,)) float64: vectors v (..., 3) rotated by unit quaternions q (..., 4), xyzw,
    broadcast to `shape` (their leading dimensions' broadcast)."""
    n = math.prod(shape)
    qb = (q if q.shape[:-1] == shape else np.broadcast_to(q, shape + (4,))).reshape(n, 4)
    vb = (v if v.shape[:-1] == shape else np.broadcast_to(v, shape + (3,))).reshape(n, 3)
    out = np.empty((n, 3))
    compiled_call(_rotate, qb, vb, out)
    return out.reshape(shape + (3,))


@njit(cache=True, nogil=True, error_model="numpy")
def _rotate(q, v, out):
    for i in range(q.shape[0]):
        x, y, z, w = (np.float64(q[i, 0]), np.float64(q[i, 1]), np.float64(q[i, 2]),
                      np.float64(q[i, 3]))
        v0, v1, v2 = np.float64(v[i, 0]), np.float64(v[i, 1]), np.float64(v[i, 2])
        out[i, 0], out[i, 1], out[i, 2] = quat_rotate1(x, y, z, w, v0, v1, v2)


_ONE = dict(cache=True, nogil=True, error_model="numpy", inline="always")


@njit(**_ONE)
def quat_rotate1(x, y, z, w, v0, v1, v2):
    """transforms.quat_rotate of one vector by (x, y, z, w)."""
    t0 = (y * v2 - z * v1) * 2.0
    t1 = (z * v0 - x * v2) * 2.0
    t2 = (x * v1 - y * v0) * 2.0
    return ((v0 + w * t0) + (y * t2 - z * t1), (v1 + w * t1) + (z * t0 - x * t2),
            (v2 + w * t2) + (x * t1 - y * t0))


@njit(**_ONE)
def quat_mul1(ax, ay, az, aw, bx, by, bz, bw):
    """transforms.quat_mul of one pair."""
    o0 = aw * bx
    o0 += ax * bw
    o0 += ay * bz
    o0 -= az * by
    o1 = aw * by
    o1 -= ax * bz
    o1 += ay * bw
    o1 += az * bx
    o2 = aw * bz
    o2 += ax * by
    o2 -= ay * bx
    o2 += az * bw
    o3 = aw * bw
    o3 -= ax * bx
    o3 -= ay * by
    o3 -= az * bz
    return o0, o1, o2, o3


@njit(**_ONE)
def quat_about1(a0, a1, a2, angle):
    """transforms.quat_about of one unit axis and angle."""
    h = 0.5 * angle
    s = math.sin(h)
    return a0 * s, a1 * s, a2 * s, math.cos(h)


@njit(**_ONE)
def cross1(a0, a1, a2, b0, b1, b2):
    """transforms.cross of one pair."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(**_ONE)
def minimum1(a, b):
    """np.minimum's choice."""
    return a if (a < b or a != a) else b


@njit(**_ONE)
def maximum1(a, b):
    """np.maximum's choice."""
    return a if (a > b or a != a) else b


@njit(**_ONE)
def normalize1(v0, v1, v2):
    """transforms.normalize of one 3-vector (eps 1e-12)."""
    m = maximum1(math.sqrt(v0 * v0 + v1 * v1 + v2 * v2), 1e-12)
    return v0 / m, v1 / m, v2 / m
