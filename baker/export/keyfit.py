"""The keyframe reduction's local pass, compiled with numba: top-down Douglas-Peucker per channel.

`fit_channels` keys, channel by channel, the worst frame of every segment that plays a frame
further than the channel's tolerance from its value, until every segment is within tolerance
(see baker.export.reduce._local_keys). A segment plays as the players do: a lerp of the stored
values for a translation or a scale, three.js's slerp for a rotation (baker.export.reduce.slerp:
the short way round, weights from the stored keys as they are, a normalized lerp for nearly
equal keys, equal keys as stored). A rotation's error is the angle between the played and the true
rotation, as baker.export.reduce._angle measures it.

A channel is keyed at every frame once it keeps more keys than `bound` (a time accessor of its
own would then cost more bytes than every frame's), and at once when more of its frames than
that miss even between their two neighbours (`tight_misses`). The keys only grow, so that
gives what splitting to the end and then promoting gives.

`_fit` writes into the keys it is given and runs on the main thread once compiled
(parallel.compiled_call); `_tight` returns its counts, and runs off the main thread
(parallel.off_main_thread), as the rasterizer's kernels do.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from baker.export.replay import NEAR_DOT, dot4
from baker.parallel import compiled_call, off_main_thread


def fit_channels(vals: np.ndarray, kept: np.ndarray, times: np.ndarray, rotation: bool,
                 tol: np.ndarray, rows: np.ndarray, bound: float, keep: np.ndarray) -> None:
    """Key the channels `rows` of keep (C, F) bool in place: vals, kept (C, F, W) float64 the
    values and the stored values (what the file holds), times (F,) float32 seconds, tol (C,)
    each channel's tolerance (metres, or radians for rotations), bound the key count past which
    a channel keeps every frame."""
    t = np.asarray(times, dtype=np.float32).astype(np.float64)
    compiled_call(_fit, np.ascontiguousarray(vals, dtype=np.float64),
                    np.ascontiguousarray(kept, dtype=np.float64), t, bool(rotation),
                    np.ascontiguousarray(tol, dtype=np.float64),
                    np.ascontiguousarray(rows, dtype=np.int64), float(bound), keep)


def tight_misses(vals: np.ndarray, kept: np.ndarray, times: np.ndarray, rotation: bool,
                 tol: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """(R,) how many frames of each of the channels `rows` (R,) (default: all) are off by more
    than tol (C,) even when played between the stored values of the frames on either side.
    vals, kept (C, F, W) (the channels picked here, not copied out)."""
    t = np.asarray(times, dtype=np.float32).astype(np.float64)
    rows = np.arange(len(vals)) if rows is None else rows
    return off_main_thread(_tight, np.ascontiguousarray(vals, dtype=np.float64),
                           np.ascontiguousarray(kept, dtype=np.float64), t, bool(rotation),
                           np.ascontiguousarray(tol, dtype=np.float64),
                           np.ascontiguousarray(rows, dtype=np.int64))


def reach(chains: np.ndarray, world: np.ndarray, out: np.ndarray) -> None:
    """out[a] = the largest of out[a] and the farthest any joint below a gets from it over all
    frames (reduce.levers), in place: chains (J, D) each joint's chain (reduce.ancestors),
    world (J, F, 3) contiguous positions, F > 0. Each distance as reduce._norm computes it."""
    compiled_call(_reach, np.ascontiguousarray(chains, dtype=np.int64), world, out)


@njit(cache=True, nogil=True, error_model="numpy")
def _reach(chains, world, out):
    for j in range(1, chains.shape[0]):
        for i in range(1, chains.shape[1]):
            a = chains[j, i]
            if a < 0:
                break                       # past the root
            far = -np.inf
            for f in range(world.shape[1]):
                d0 = world[j, f, 0] - world[a, f, 0]
                d1 = world[j, f, 1] - world[a, f, 1]
                d2 = world[j, f, 2] - world[a, f, 2]
                d = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                if d > far or d != d:       # max's and np.maximum's (a NaN wins)
                    far = d
            if far > out[a] or far != far:
                out[a] = far


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _alpha(t, p, n, f):
    span = t[n] - t[p]
    return (t[f] - t[p]) / span if span > 0.0 else 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def _worst(vals, kept, t, c, p, n, rotation, tol, cos_lo, est):
    """(error, frame) of the worst frame strictly between the keys p and n of channel c that
    plays further than tol from its value (the earliest of equal errors), or (-1, -1) when
    none does. The slerp's angle between the two keys is the segment's, computed once; a
    rotation's angle (an arccos) only where the cosine is within cos_lo, so it can miss."""
    worst, at = -1.0, -1
    v0, v1 = kept[c, p], kept[c, n]
    if rotation:
        d = dot4(v0, v1)
        s = 1.0
        if d < 0.0:
            s, d = -1.0, -d
        same = v0[0] == s * v1[0] and v0[1] == s * v1[1] and v0[2] == s * v1[2] and \
            v0[3] == s * v1[3]
        near = d >= NEAR_DOT
        theta = sn = 0.0
        if not (same or near):
            theta = np.arccos(min(d, 1.0))
            sn = np.sin(theta)
    for f in range(p + 1, n):
        a = _alpha(t, p, n, f)
        v = vals[c, f]
        if not rotation:
            e2 = 0.0
            for k in range(len(v)):
                x = v0[k] + a * (v1[k] - v0[k]) - v[k]
                e2 += x * x
            e = np.sqrt(e2)
        else:
            if same:
                for k in range(4):
                    est[k] = v0[k]
            else:
                if near:
                    wa, wb = 1.0 - a, a
                else:
                    wa, wb = np.sin((1.0 - a) * theta) / sn, np.sin(a * theta) / sn
                wb *= s
                for k in range(4):
                    est[k] = v0[k] * wa + v1[k] * wb
                if near:
                    m = np.sqrt(dot4(est, est))
                    for k in range(4):
                        est[k] /= m
            cosine = abs(dot4(v, est)) / (np.sqrt(dot4(v, v)) * np.sqrt(dot4(est, est)))
            if cosine > cos_lo:
                continue
            e = 2.0 * np.arccos(min(max(cosine, 0.0), 1.0))
        if e > tol and e > worst:
            worst, at = e, f
    return worst, at


@njit(cache=True, nogil=True, error_model="numpy")
def _fit(vals, kept, t, rotation, tol, rows, bound, keep):
    f_count = vals.shape[1]
    est = np.empty(4)
    stack = np.empty((2 * f_count + 2, 2), np.int64)
    for c in rows:
        # a cosine above cos_lo is an angle below the tolerance, whatever the rounding
        cos_lo = np.cos(0.5 * tol[c]) + 1e-9
        keep[c, 0] = keep[c, f_count - 1] = True
        count = 1 if f_count == 1 else 2
        stack[0, 0], stack[0, 1] = 0, f_count - 1
        top = 1
        while top > 0 and count <= bound:
            top -= 1
            p, n = stack[top, 0], stack[top, 1]
            at = _worst(vals, kept, t, c, p, n, rotation, tol[c], cos_lo, est)[1]
            if at < 0:
                continue
            keep[c, at] = True
            count += 1
            stack[top, 0], stack[top, 1] = at, n
            stack[top + 1, 0], stack[top + 1, 1] = p, at
            top += 2
        if count > bound:
            keep[c, :] = True


@njit(cache=True, nogil=True, error_model="numpy")
def _tight(vals, kept, t, rotation, tol, rows):
    f_count = vals.shape[1]
    out = np.zeros(len(rows), np.int64)
    est = np.empty(4)
    for r in range(len(rows)):
        c = rows[r]
        cos_lo = np.cos(0.5 * tol[c]) + 1e-9
        for f in range(1, f_count - 1):
            if _worst(vals, kept, t, c, f - 1, f + 1, rotation, tol[c], cos_lo, est)[1] >= 0:
                out[r] += 1
    return out
