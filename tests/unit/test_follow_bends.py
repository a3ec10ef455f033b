"""The follower's trail bends measured one pair of chords at a time as its points are pushed
(run.follow.bend_radius, Follower._bend_at) against the numpy measure of the whole trail under
the body they replace: the same bits, on random trails with hairpins, straight runs and repeated
points."""

from __future__ import annotations

import math

import numpy as np

from baker.run.follow import _BEND_CHORD, bend_radius


def whole_trail(points: np.ndarray, k: int) -> float:
    """The smallest bend radius of the trail (n, 2), over every pair of chords k points long, in
    numpy over the whole trail (as the follower measured it before)."""
    if len(points) < 2 * k + 1:
        return math.inf
    a = points[k:-k] - points[:-2 * k]
    b = points[2 * k:] - points[k:-k]
    la, lb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    ok = (la > 1e-9) & (lb > 1e-9)
    if not ok.any():
        return math.inf
    cos = np.sum(a[ok] * b[ok], axis=1) / (la[ok] * lb[ok])
    ang = np.arccos(np.clip(cos, -1.0, 1.0))
    r = 0.5 * (la[ok] + lb[ok]) / np.maximum(ang, 1e-12)
    return float(r.min())


def trail(rng: np.random.Generator, n: int) -> np.ndarray:
    """A random walk of n points a step apart, turning by random amounts (hairpins among
    them), with runs of straight steps and of repeated points."""
    turn = rng.normal(0.0, 0.3, n) + np.where(rng.random(n) < 0.05, np.pi, 0.0)
    turn[rng.random(n) < 0.3] = 0.0
    yaw = np.cumsum(turn)
    step = np.where(rng.random(n) < 0.05, 0.0, 0.0075)
    pts = np.cumsum(np.stack([step * np.cos(yaw), step * np.sin(yaw)], axis=1), axis=0)
    return pts + rng.uniform(-50.0, 50.0, 2)


def test_pairs_match_the_whole_trail():
    rng = np.random.default_rng(7)
    k = _BEND_CHORD
    for _ in range(400):
        pts = trail(rng, int(rng.integers(1, 120)))
        rows = pts.tolist()
        pairs = [bend_radius(*rows[i - 2 * k], *rows[i - k], *rows[i])
                 for i in range(2 * k, len(rows))]
        got = min(pairs, default=math.inf)
        want = whole_trail(pts, k)
        assert got == want or (math.isinf(got) and math.isinf(want))
        assert np.float64(got).tobytes() == np.float64(want).tobytes()
