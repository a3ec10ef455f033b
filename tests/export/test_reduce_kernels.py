"""The keyframe reduction's compiled kernels (export.keyfit, export.replay) against plain numpy:
the local pass keeps the keys that plain top-down splitting keeps, the SHORT quantization picks
the codes quantize_rotations picks, and a signal during a compiled call stops cleanly. (The
player's replay against a fresh playback, and the bound in the files: test_reduce.py.)"""

from __future__ import annotations

import numpy as np
import pytest
from signal_stops import assert_signals_stop_cleanly

from baker.export import reduce as red
from baker.export import replay


def _plain_keys(values, stored, times, rotation, tol, bound):
    """(C, F) keys of plain top-down splitting, one segment at a time with the module's numpy
    slerp and errors, every frame for a channel that ends with more than `bound` keys."""
    f_count, c_count, _ = values.shape
    t = np.asarray(times, np.float32).astype(np.float64)
    keep = np.zeros((c_count, f_count), dtype=bool)
    for c in range(c_count):
        keep[c, [0, -1]] = True
        todo = [(0, f_count - 1)]
        while todo:
            p, n = todo.pop()
            f = np.arange(p + 1, n)
            if not len(f):
                continue
            a = (t[f] - t[p]) / (t[n] - t[p])
            v0 = np.broadcast_to(stored[p, c].astype(np.float64), (len(f), values.shape[2]))
            v1 = np.broadcast_to(stored[n, c].astype(np.float64), v0.shape)
            true = values[f, c].astype(np.float64)
            if rotation:
                err = red._rotation_error(true, red.slerp(v0, v1, a))
            else:
                err = np.linalg.norm(v0 + a[:, None] * (v1 - v0) - true, axis=-1)
            if not (err > tol[c]).any():
                continue
            w = int(f[np.argmax(np.where(err > tol[c], err, -1.0))])
            keep[c, w] = True
            todo += [(p, w), (w, n)]
        if keep[c].sum() > bound:
            keep[c] = True
    return keep


def _channels(rng, f_count, rotation):
    """(F, 6, W) float32 test channels: smooth curves of several speeds, noisy ones, a still
    one, and (rotations) one that crosses to the other hemisphere (the short way round)."""
    s = np.linspace(0.0, 1.0, f_count)[:, None]
    if not rotation:
        curves = [np.hstack([np.sin(k * 3.0 * s), 0.02 * np.cos(k * s), 0 * s]) * 0.1
                  for k in (1, 3, 9)]
        curves += [curves[0] + rng.normal(0.0, 2e-4, curves[0].shape),
                   curves[1] + rng.normal(0.0, 3e-5, curves[1].shape), 0 * curves[0]]
        return np.stack(curves, 1).astype(np.float32)
    angles = np.hstack([np.sin(k * 2.0 * s) for k in (1, 3, 7)]) * np.array([0.8, 0.4, 0.2])
    rows = [angles, angles * 3.0, angles + rng.normal(0.0, 2e-3, angles.shape),
            angles * 0.01, 0 * angles, np.hstack([4.0 * s, 0 * s, 0 * s])]
    out = []
    for r in rows:
        half = np.linalg.norm(r, axis=1, keepdims=True) / 2
        axis = r / np.maximum(2 * half, 1e-12)
        q = np.hstack([axis * np.sin(half), np.cos(half)])
        out.append(q)
    return np.stack(out, 1).astype(np.float32)


@pytest.mark.parametrize("rotation", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_local_pass_keeps_what_plain_splitting_keeps(rotation, seed):
    rng = np.random.default_rng(seed)
    f_count = 301
    values = _channels(rng, f_count, rotation)
    stored = (red.dequantize_rotations(red.quantize_rotations(values)) if rotation
              else values)
    times = (np.arange(f_count) / 30.0).astype(np.float32)
    tol = np.full(values.shape[1], 2e-3 if rotation else 2e-4)
    value_bytes = 8 if rotation else 12
    keep, static = red._local_keys(values, stored, times, rotation, tol, None, value_bytes)
    bound = value_bytes * f_count / (value_bytes + red.TIME_BYTES)
    first = np.broadcast_to(values[:1].astype(np.float64), values.shape)
    off = (red._rotation_error(values.astype(np.float64), first) if rotation
           else np.linalg.norm(values - first, axis=-1)).max(axis=0)
    plain = _plain_keys(values, stored, times, rotation, tol, bound)
    plain[off <= tol] = False              # static channels: no keys
    assert np.array_equal(keep, plain)
    # the spread of outcomes the channels are for: static, sparse, dense
    counts = keep.sum(axis=1)
    assert (counts == 0).any() and ((counts > 2) & (counts < bound)).any()
    assert (counts == f_count).any()


def test_compiled_quantization_picks_the_codes_of_quantize_rotations():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(4000, 4))
    q[:500, :3] *= 1e-4                     # near identity
    q[500:1000, 1:] = 0.0                   # on an axis
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    want = red.quantize_rotations(q)
    got = np.empty_like(want)
    for i, row in enumerate(q):
        replay._quantize(row, got[i])
    assert np.array_equal(got, want)


def test_signals_during_the_compiled_reduction_stop_cleanly():
    """As for the rasterizer (test_navmesh_raster): 100 SIGTERMs at staggered moments during
    repeated compiled calls, each raising in the main thread, stop them cleanly (the key
    fitting's kernel runs on the main thread once compiled: parallel.compiled_call)."""
    assert_signals_stop_cleanly("""
        from baker.export import keyfit
        rng = np.random.default_rng(0)
        v = np.cumsum(rng.normal(0, 1e-3, (400, 3000, 3)), axis=1)
        t = (np.arange(3000) / 30.0).astype(np.float32)
        tol = np.full(400, 1e-4)
        """, """
        keep = np.zeros((400, 3000), dtype=bool)
        keyfit.fit_channels(v, v, t, False, tol, np.arange(400), 2500.0, keep)
        keyfit.tight_misses(v, v, t, False, tol)
        """, times=100)
