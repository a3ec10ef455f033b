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


@pytest.mark.parametrize("seed", range(6))
def test_quat_rotate_on_large_batches_gives_the_numpy_forms_bits(seed, monkeypatch):
    """quat_rotate's compiled pass (geometry.fused, batches of FUSED_ROTATE or more) against
    its numpy form, bit for bit: broadcast shapes, float32 inputs, strided views, vectors of
    any length and quaternions not quite unit."""
    from baker.geometry import transforms as tr

    rng = np.random.default_rng(seed)
    F, L = int(rng.integers(600, 1200)), int(rng.integers(1, 30))
    q = rng.normal(size=(F, L, 4)) * rng.uniform(0.9, 1.1, (F, L, 1))
    q /= np.linalg.norm(q, axis=-1, keepdims=True) if seed % 2 else 1.0
    cases = [(q, rng.normal(size=(F, L, 3)) * 10.0 ** rng.uniform(-6, 3, (F, L, 1))),
             (q, np.broadcast_to([0.0, 1.0, 0.0], (F, L, 3))),
             (q[:, :1], rng.normal(size=(F, L, 3))),
             (q[::2, ::-1], rng.normal(size=(L, 3))),
             (q.astype(np.float32), rng.normal(size=(F, L, 3)).astype(np.float32)),
             (q.reshape(-1, 4), np.array([0.0, 0.0, 1.0]))]
    for qq, vv in cases:
        got = tr.quat_rotate(qq, vv)
        monkeypatch.setattr(tr, "FUSED_ROTATE", 1 << 62)
        want = tr.quat_rotate(qq, vv)
        monkeypatch.undo()
        assert got.dtype == want.dtype and got.shape == want.shape
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))


def _frames(rng, n, parallel=0):
    """Rotation matrices built as ik.bone_frames builds them (y along a bone, x the hinge made
    orthogonal, z = x cross y), some hinges nearly along the bone, the first `parallel` exactly
    along it (a zero x column)."""
    y = normalize(rng.normal(size=(n, 3)))
    hinge = rng.normal(size=(n, 3))
    near = rng.random(n) < 0.1
    hinge[near] = y[near] + rng.normal(size=(near.sum(), 3)) * 10.0 ** rng.uniform(-9, -3, (near.sum(), 1))
    hinge[:parallel] = 2.0 * y[:parallel]
    x = normalize(hinge - dot(hinge, y)[:, None] * y)
    return np.stack([x, y, cross(x, y)], axis=-1)


@pytest.mark.parametrize("seed", range(3))
def test_frame_quats_are_scipys_validated_bits(seed):
    """frame_quats skips scipy's validation only where it changes nothing: the same bits as
    Rotation.from_matrix on frames made as the solve makes them, hinges nearly along the bone
    included."""
    from scipy.spatial.transform import Rotation

    from baker.geometry.transforms import frame_quats

    m = _frames(np.random.default_rng(seed), 100_000)
    want = Rotation.from_matrix(m).as_quat()
    got = frame_quats(m)
    assert np.array_equal(got.view(np.int64), want.view(np.int64))
    assert np.array_equal(frame_quats(m.reshape(100, 1000, 3, 3)), want.reshape(100, 1000, 4))


def test_frame_quats_leave_degenerate_frames_to_scipys_check():
    """A zero column (a hinge along the bone) still fails as scipy's validated call fails; NaN
    frames go the validated way too."""
    from scipy.spatial.transform import Rotation

    from baker.geometry.transforms import frame_quats

    m = _frames(np.random.default_rng(7), 50, parallel=1)
    with pytest.raises(ValueError):
        Rotation.from_matrix(m)
    with pytest.raises(ValueError):
        frame_quats(m)
    m = _frames(np.random.default_rng(8), 50)
    m[3, 0, 0] = np.nan
    with np.errstate(invalid="ignore"):         # scipy's determinant of the NaN frame
        try:
            want = Rotation.from_matrix(m).as_quat()
        except np.linalg.LinAlgError:
            with pytest.raises(np.linalg.LinAlgError):
                frame_quats(m)
        else:
            assert np.array_equal(frame_quats(m), want, equal_nan=True)
