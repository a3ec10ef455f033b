"""What the centipede senses: shade (a ray toward the sun), prey, obstacles worth rearing at.
Every check takes arrays and casts its rays in one call."""

from __future__ import annotations

import numpy as np

from baker.geometry.conventions import UP


def in_shade(rays, points: np.ndarray, sun_dir: np.ndarray, lift: float) -> np.ndarray:
    """(n,) bool: True where a ray from each point (raised by `lift`) toward the sun is blocked.

    points : (n, 3) world, sun_dir : (3,) or (n, 3) unit vectors toward the sun
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3) + lift * UP
    d = np.broadcast_to(np.asarray(sun_dir, dtype=np.float64), pts.shape)
    return rays.occluded(pts, d)


def obstacle_ahead(rays, head: np.ndarray, heading: np.ndarray, probe: float,
                   low: float, high: float) -> bool:
    """True when something blocks the way ahead at `low` height above the head's surface point
    but not at `high`: an obstacle taller than a step and low enough to rear up at."""
    o = np.array([head + low * UP, head + high * UP])
    d = np.tile(heading, (2, 1))
    hit = rays.occluded(o, d, probe)
    return bool(hit[0] and not hit[1])
