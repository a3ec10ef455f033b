"""Cobra mode: the front of the body rises along an editable curve while the rest stays on the
trail. The curve is sampled at 1 - i/n for joint i of n (SEED.md): the head gets the curve's
value at 1, the tail its value near 0.

Raised joints keep their spacing: each joint is re-placed on the trail at the point whose 3D
distance to the joint ahead is exactly the rig spacing, so the raised neck pulls the body
forward along its path instead of stretching it. Lifts are limited by upward rays so a raised
joint never enters geometry above it.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import PchipInterpolator

from baker.geometry import polyline
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
    x = 1.0 - np.arange(segments) / (segments - 1)
    a = np.clip(amount, 0.0, 1.0)
    ease = a * a * (3.0 - 2.0 * a)
    return height * ease[:, None] * curve_values(keys, x)[None, :]


def raise_front(trail_points: np.ndarray, trail_cum: np.ndarray, head_arc: np.ndarray,
                positions: np.ndarray, lift: np.ndarray, spacing: float, clearance: float,
                rays, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Spine positions with the lift applied.

    trail_points, trail_cum : the trail polyline and its 3D arc lengths
    head_arc  : (F,) head arc length on the trail
    positions : (F, S, 3) unraised spine (trail point + clearance * UP)
    lift      : (F, S) requested lift, metres
    returns (positions (F, S, 3), applied lift (F, S)); frames without lift are unchanged.
    """
    out = positions.copy()
    lift = lift.copy()
    frames = np.nonzero(lift.max(axis=1) > 1e-9)[0]
    if len(frames) == 0:
        return out, lift
    L = lift[frames]
    S = L.shape[1]
    # Ceiling: rays up from each raised joint's unraised position.
    f_idx, j_idx = np.nonzero(L > 1e-9)
    base = positions[frames][f_idx, j_idx]
    up = np.tile(UP, (len(base), 1))
    hits = rays.first_hit(base, up, max_distance=L[f_idx, j_idx] + margin + 1e-6)
    room = np.where(hits.hit, hits.distance - margin, np.inf)
    L[f_idx, j_idx] = np.clip(np.minimum(L[f_idx, j_idx], room), 0.0, None)
    # Smooth the clamped profile along the body so a low ceiling bends, not breaks, the neck.
    for _ in range(2):
        L = np.minimum(L, np.concatenate([L[:, :1], L[:, :-1]], axis=1) + 0.5 * spacing)
    lift[frames] = L

    ha = head_arc[frames]
    p = np.empty((len(frames), S, 3))
    p[:, 0] = polyline.sample(trail_points, trail_cum, ha) + (clearance + L[:, 0:1]) * UP
    u_prev = np.zeros(len(frames))
    for i in range(1, S):
        prev = p[:, i - 1]
        off = (clearance + L[:, i:i + 1]) * UP

        def dist(u):
            q = polyline.sample(trail_points, trail_cum, ha - u) + off
            return np.linalg.norm(q - prev, axis=1), q

        lo = u_prev.copy()
        hi = u_prev + 2.0 * spacing
        for _ in range(24):  # bisection on the arc: distance to the joint ahead == spacing
            mid = 0.5 * (lo + hi)
            d, _ = dist(mid)
            far = d > spacing
            hi = np.where(far, mid, hi)
            lo = np.where(far, lo, mid)
        u_prev = 0.5 * (lo + hi)
        _, p[:, i] = dist(u_prev)
    out[frames] = p
    return out, lift
