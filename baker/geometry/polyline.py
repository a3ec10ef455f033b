"""Polylines parameterized by arc length. Interpolation is exact (piecewise linear)."""

import numpy as np

from baker.geometry.transforms import length


def arc_lengths(points: np.ndarray) -> np.ndarray:
    """Cumulative arc length at each vertex.

    points : (n, d) float -> (n,) float, starts at 0
    """
    points = np.asarray(points, dtype=np.float64)
    if len(points) == 0:
        return np.zeros(0)
    seg = length(np.diff(points, axis=0))
    return np.concatenate([[0.0], np.cumsum(seg)])


def sample(points: np.ndarray, cum: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Points at arc lengths `s` along the polyline (clamped to its ends).

    points : (n, d) float, cum : (n,) from arc_lengths (non-decreasing), s : (...) float
    returns : (..., d) float
    """
    s = np.asarray(s, dtype=np.float64)
    flat = np.clip(s.ravel(), cum[0], cum[-1])
    i = np.clip(np.searchsorted(cum, flat, side="right") - 1, 0, max(len(cum) - 2, 0))
    if len(cum) == 1:
        return np.broadcast_to(points[0], s.shape + points.shape[1:]).copy()
    seg = cum[i + 1] - cum[i]
    t = np.where(seg > 0, (flat - cum[i]) / np.where(seg > 0, seg, 1.0), 0.0)
    out = points[i] + t[:, None] * (points[i + 1] - points[i])
    return out.reshape(s.shape + points.shape[1:])


def tangents(points: np.ndarray, cum: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Unit direction of the polyline segment containing each arc length `s`.

    returns : (..., d) float; zero vectors for degenerate polylines
    """
    s = np.asarray(s, dtype=np.float64)
    flat = np.clip(s.ravel(), cum[0], cum[-1])
    if len(cum) < 2:
        return np.zeros(s.shape + points.shape[1:])
    i = np.clip(np.searchsorted(cum, flat, side="right") - 1, 0, len(cum) - 2)
    d = points[i + 1] - points[i]
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return (d / np.maximum(n, 1e-12)).reshape(s.shape + points.shape[1:])
