"""What the centipede senses: shade (a ray toward the sun), prey, obstacles worth rearing at,
and whether a point is on another floor. Every check takes arrays and casts its rays (or
queries the walkable surface) in one call."""

from __future__ import annotations

import numpy as np

from baker.geometry.conventions import UP

#: [m] a height far below any level, where the nearest walkable layer is a column's lowest
FAR_BELOW = 1.0e4


def in_shade(rays, points: np.ndarray, sun_dir: np.ndarray, lift: float) -> np.ndarray:
    """(n,) bool: True where a ray from each point (raised by `lift`) toward the sun is blocked.

    points : (n, 3) world, sun_dir : (3,) or (n, 3) unit vectors toward the sun
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3) + lift * UP
    return rays.occluded(pts, sun_dir)


def obstacles_ahead(rays, heads: np.ndarray, headings: np.ndarray, probe: float,
                    low: float, high: float) -> np.ndarray:
    """(n,) bool: for each head (n, 3) and its heading (n, 3), something blocks the way ahead
    at `low` height above the head's surface point but not at `high`: an obstacle taller than
    a step and low enough to rear up at."""
    heads = np.asarray(heads, dtype=np.float64)
    o = np.stack([heads + low * UP, heads + high * UP], axis=1).reshape(-1, 3)
    d = np.repeat(np.asarray(headings, dtype=np.float64), 2, axis=0)
    hit = rays.occluded(o, d, probe).reshape(-1, 2)
    return hit[:, 0] & ~hit[:, 1]


def on_another_floor(nav, head: np.ndarray, target: np.ndarray, rise: float) -> bool:
    """True when walking from the head to the target changes floors: the target is at least
    `rise` above or below the head, and the path between them runs somewhere over another
    walkable layer at least `rise` below it (the terrace over the room under it, the bridge
    over the passage). A hillside is not another floor, nor is a bank as high as a leaf the
    head walks under.

    nav : the walkable surface (navmesh protocol: find_path, resample_path, surface_height)
    """
    head = np.asarray(head, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    if abs(float(target[1] - head[1])) < rise:
        return False
    path = nav.find_path(head, target).points
    # every half rise, but no finer than the surface's cells (a rig's tiny rise would otherwise
    # ask for millions of points along the path)
    pts = nav.resample_path(path, max(0.5 * rise, nav.cell_size))
    deep = pts.copy()
    deep[:, 1] -= FAR_BELOW
    lowest = nav.surface_height(deep)        # the lowest walkable layer in each column
    return bool(np.any(lowest <= pts[:, 1] - rise))
