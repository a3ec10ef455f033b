"""transforms.quat_rotate on large batches in one compiled pass (numba), with the numpy form's
arithmetic element by element, so the same bits: t = 2 cross(q.xyz, v), then
(v + w t) + cross(q.xyz, t), each cross product's component a_i b_j - a_j b_i. The numpy form
makes a dozen passes over strided component views and their temporaries; this makes one.

Imported by transforms on its first large batch (the CLI's option errors come before numba is
imported). The kernel writes into the array it is given and runs on the main thread once
compiled (parallel.compiled_call).
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
        t0 = (y * v2 - z * v1) * 2.0
        t1 = (z * v0 - x * v2) * 2.0
        t2 = (x * v1 - y * v0) * 2.0
        out[i, 0] = (v0 + w * t0) + (y * t2 - z * t1)
        out[i, 1] = (v1 + w * t1) + (z * t0 - x * t2)
        out[i, 2] = (v2 + w * t2) + (x * t1 - y * t0)
