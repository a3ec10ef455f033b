"""Analytic two-bone IK, vectorized over any leading axes (frames x legs).

The chain is root -> mid -> end with bone lengths l1, l2. The mid joint (the knee) bends toward
a pole direction, so the solution is unique and never flips while the pole stays off the
root->target line. Targets out of reach are clamped smoothly: the reach saturates like
1 - exp(-x) instead of snapping straight, and targets too close are pushed out the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baker.geometry.transforms import cross, dot, frame_quats, length, normalize

#: fraction of the full reach (l1 + l2) where the soft clamp starts
SOFT_START = 0.96


@dataclass(frozen=True)
class TwoBoneSolution:
    """mid : (..., 3) knee positions; end : (..., 3) reached end positions (== target when in
    reach); reach : (..., ) root->end distance used; clamped : (...,) bool, end != target."""

    mid: np.ndarray
    end: np.ndarray
    reach: np.ndarray
    clamped: np.ndarray
    hinge: np.ndarray


def soft_clamp(d: np.ndarray, lo: float | np.ndarray, hi: float | np.ndarray,
               soft: float = SOFT_START) -> np.ndarray:
    """Distances `d` squashed into [lo, hi] smoothly (C1): identity inside
    [lo + (1 - soft) hi, soft hi], exponential saturation beyond. lo, hi broadcast with d."""
    d = np.asarray(d, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    lo = np.asarray(lo, dtype=np.float64)
    s_hi = soft * hi
    w_hi = np.maximum(hi - s_hi, 1e-300)
    out = np.where(d > s_hi, s_hi + w_hi * (1.0 - np.exp(-(d - s_hi) / w_hi)), d)
    s_lo = lo + (1.0 - soft) * hi
    w_lo = np.maximum(s_lo - lo, 1e-300)
    out = np.where(out < s_lo, s_lo - w_lo * (1.0 - np.exp(-(s_lo - out) / w_lo)), out)
    return out


def reach_clamp(d: np.ndarray, l1, l2) -> np.ndarray:
    """The reach two_bone_ik solves for at distance d (...) of bones l1, l2: d soft-clamped
    into [|l1 - l2| + 1e-6 (l1 + l2), l1 + l2]."""
    return soft_clamp(d, np.abs(l1 - l2) + 1e-6 * (l1 + l2), l1 + l2)


def two_bone_ik(root: np.ndarray, target: np.ndarray, pole: np.ndarray,
                l1: float | np.ndarray, l2: float | np.ndarray) -> TwoBoneSolution:
    """Solve root -> mid -> end so that end is at `target` (or as close as the soft clamp lets).

    root, target, pole : (..., 3) float, world; `pole` is a direction (from root) the knee bends
                         toward, e.g. up and outward; only its part perpendicular to root->target
                         matters
    l1, l2             : bone lengths, scalars or broadcastable to (...)
    Bone lengths are preserved exactly: |mid - root| == l1, |end - mid| == l2.
    """
    root = np.asarray(root, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    l1 = np.asarray(l1, dtype=np.float64)
    l2 = np.asarray(l2, dtype=np.float64)
    v = target - root
    d_raw = length(v)
    u = v / np.maximum(d_raw, 1e-12)[..., None]
    # degenerate target at the root: reach along the pole's perpendicular fallback
    # (its np.where skipped where no target is degenerate: the same array)
    ok = d_raw > 1e-12
    if not (ok.all() and np.shape(pole) == u.shape):
        u = np.where(ok[..., None], u, normalize(cross(pole, [0.0, 0.0, 1.0]) + 1e-9))
    d = reach_clamp(d_raw, l1, l2)
    hi = l1 + l2
    p = np.asarray(pole, dtype=np.float64)
    w = p - dot(p, u)[..., None] * u
    wn = length(w)[..., None]
    # pole (anti)parallel to the chain: pick any perpendicular, deterministically
    # (skipped as above where no pole is)
    if (wn > 1e-9).all() and w.shape == u.shape:
        w = w / np.maximum(wn, 1e-300)
    else:
        alt = cross(u, np.where(np.abs(u[..., 1:2]) < 0.9, [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]))
        w = np.where(wn > 1e-9, w / np.maximum(wn, 1e-300), normalize(alt))
    a = (l1 * l1 - l2 * l2 + d * d) / (2.0 * d)
    h = np.sqrt(np.maximum(l1 * l1 - a * a, 0.0))
    mid = root + a[..., None] * u + h[..., None] * w
    end = root + d[..., None] * u
    # re-impose the second length exactly against rounding
    end = mid + normalize(end - mid) * np.expand_dims(l2, -1)
    return TwoBoneSolution(mid=mid, end=end, reach=d, clamped=np.abs(d - d_raw) > 1e-9 * hi,
                           hinge=cross(u, w))


def bone_frames(start: np.ndarray, end: np.ndarray, hinge: np.ndarray) -> np.ndarray:
    """World rotations of bones: local +Y along start->end, local +X along the hinge axis
    (made orthogonal), +Z = X x Y.

    start, end, hinge : (..., 3) -> (..., 4) xyzw
    """
    y = normalize(np.asarray(end, float) - np.asarray(start, float))
    x = np.asarray(hinge, float)
    x = normalize(x - dot(x, y)[..., None] * y)
    z = cross(x, y)
    return frame_quats(np.stack([x, y, z], axis=-1))
