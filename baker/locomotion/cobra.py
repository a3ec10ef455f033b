"""Cobra mode: the front of the body rises along an editable curve while the rest stays on the
trail. The curve is sampled at 1 - i/n for joint i of n (SEED.md): the head gets the curve's
value at 1, the tail its value near 0.

Raised joints keep their spacing (the body stage places every joint exactly one spacing from
the joint ahead), so the raised neck pulls the body forward along its path instead of
stretching it. Lifts are limited by upward rays so a raised joint never enters geometry above
it, and the limit is smoothed along the body and over time.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.ndimage import minimum_filter1d, uniform_filter1d

from baker.geometry.conventions import UP


def curve_values(keys, x: np.ndarray) -> np.ndarray:
    """Monotone smooth interpolation of curve keys ((x, y), ...) at x in [0, 1]."""
    k = np.asarray(keys, dtype=np.float64)
    if len(k) == 1:
        return np.full_like(np.asarray(x, float), k[0, 1])
    return PchipInterpolator(k[:, 0], k[:, 1], extrapolate=True)(np.clip(x, k[0, 0], k[-1, 0]))


def lift_profile(amount: np.ndarray, keys, height: float, segments: int) -> np.ndarray:
    """(F, S) requested lift per joint: height * ease(amount) * curve(1 - i/n).

    amount : (F,) 0..1, how far the cobra pose has risen (ramped by the simulation)
    """
    a = np.clip(amount, 0.0, 1.0)
    ease = a * a * (3.0 - 2.0 * a)
    return height * ease[:, None] * _joint_curve(_hashable(keys), segments)[None, :]


def _hashable(keys) -> tuple:
    return tuple(tuple(float(v) for v in k) for k in np.asarray(keys, dtype=np.float64))


@functools.lru_cache(maxsize=16)
def _joint_curve(keys: tuple, segments: int) -> np.ndarray:
    """curve_values of keys at 1 - i/n for each of the segments (read only, kept: a crowd's
    run asks for the profile of each new cobra amount of its bodies)."""
    out = curve_values(keys, 1.0 - np.arange(segments) / (segments - 1))
    out.flags.writeable = False
    return out


def limit_lift(positions: np.ndarray, lift: np.ndarray, spacing: float, rays, margin: float,
               fps_frames: int) -> np.ndarray:
    """Requested lift (F, S) limited by the room above each joint's unraised position (rays
    up). The limit is smoothed over time (the lift lowers ahead of an overhang, over
    `fps_frames` frames, rather than snapping down under it) and applied as one factor per
    frame, so the raised front keeps the curve's shape, only lower."""
    f_idx, j_idx = np.nonzero(lift > 1e-9)
    if len(f_idx) == 0:
        return lift.copy()
    base = positions[f_idx, j_idx]
    up = np.tile(UP, (len(base), 1))
    t, _ = rays.cast(base, up, lift[f_idx, j_idx] + margin + 1e-6)
    room = np.full(lift.shape, np.inf)
    room[f_idx, j_idx] = np.where(np.isfinite(t), t - margin, np.inf)
    if not np.isfinite(room).any():
        return lift.copy()
    w = max(int(fps_frames), 1)
    capped = np.minimum(room, lift.max())
    capped = minimum_filter1d(capped, size=2 * w + 1, axis=0, mode="nearest")
    capped = uniform_filter1d(capped, size=w + 1, axis=0, mode="nearest")
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(lift > 1e-9, np.clip(capped, 0.0, None) / lift, np.inf)
    factor = np.clip(ratio.min(axis=1), 0.0, 1.0)
    return lift * factor[:, None]
