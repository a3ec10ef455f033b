"""geometry/transforms.py's fast forms give numpy's own bits: dot and length sum a 3- or 4-long
last axis left to right as np.sum and np.linalg.norm do, cross and quat_mul write each component
in place (bakes stay byte-identical only if these hold)."""

from __future__ import annotations

import numpy as np
import pytest

from baker.geometry.transforms import cross, dot, length, normalize, quat_mul

SHAPES = [(1, 3), (257, 3), (7, 5, 3), (1, 4), (300, 4), (6, 9, 4)]


def _arrays(shape, seed):
    rng = np.random.default_rng(seed)
    scale = 10.0 ** rng.uniform(-6, 4, size=shape[:-1] + (1,))
    return rng.normal(size=shape) * scale, rng.normal(size=shape) * scale


@pytest.mark.parametrize("shape", SHAPES, ids=str)
def test_dot_length_and_normalize_give_numpys_bits(shape):
    a, b = _arrays(shape, 1)
    assert np.array_equal(dot(a, b), np.sum(a * b, axis=-1))
    assert np.array_equal(length(a), np.linalg.norm(a, axis=-1))
    n = np.linalg.norm(a, axis=-1, keepdims=True)
    assert np.array_equal(normalize(a), a / np.maximum(n, 1e-12))
    # a non-contiguous view (every other row) and float32 take numpy's own path
    assert np.array_equal(dot(a[::2], b[::2]), np.sum(a[::2] * b[::2], axis=-1))
    a32 = a.astype(np.float32)
    assert np.array_equal(length(a32), np.linalg.norm(a32, axis=-1))


@pytest.mark.parametrize("shape", [s for s in SHAPES if s[-1] == 3], ids=str)
def test_cross_gives_np_cross_bits_and_broadcasts(shape):
    a, b = _arrays(shape, 2)
    assert np.array_equal(cross(a, b), np.cross(a, b))
    assert np.array_equal(cross(a, b[:1]), np.cross(a, b[:1]))      # broadcast


def test_quat_mul_matches_the_stacked_hamilton_product():
    a, b = _arrays((50, 4), 3)

    def stacked(a, b):
        ax, ay, az, aw = np.moveaxis(a, -1, 0)
        bx, by, bz, bw = np.moveaxis(b, -1, 0)
        return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                         aw * by - ax * bz + ay * bw + az * bx,
                         aw * bz + ax * by - ay * bx + az * bw,
                         aw * bw - ax * bx - ay * by - az * bz], axis=-1)

    assert np.array_equal(quat_mul(a, b), stacked(a, b))
    assert np.array_equal(quat_mul(a[:, None], b[None]), stacked(a[:, None], b[None]))
