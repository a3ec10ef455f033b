"""A navigation surface built lazily, only where the creatures go.

On a level too large to build whole at the agent's cell size (a 0.25 m centipede's 1.5 cm cells
on a 200 m game map would be 180 million columns), the surface is built over a window around the
start, and the window grows when a query reaches beyond it: a random point whose disc, a path
whose corridor, or a nearest point that falls outside. Each growth rebuilds the surface over the
larger window (the ray casting is the bulk of a build, and windows grow by at least half their
size each time, so the total cost stays within a small factor of one build of the final
window). The cost is in proportion to the area the bake uses, not to the level's size.

Windows are snapped outward to a grid of tiles (TILE_CELLS cells), so the on-disk cache (keyed
by the window's bounds) is shared between bakes that walk the same part of the level. Every
decision depends only on the queries, which depend only on the seed: the same seed builds the
same windows, and gives the same results whether they come from the cache or not.

LazyNav satisfies the Navigation protocol (protocol.py) as NavSurface does: the queries that
can reach beyond the window grow it first, the other queries and the data attributes are the
current window's NavSurface's. Anything else (the arrays, prepare, ...) is forwarded to it too,
so a LazyNav stands in for a NavSurface wherever one is used.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from baker.errors import BudgetError, NavError
from baker.navmesh.cache import load_or_build
from baker.navmesh.query import NavSurface

log = logging.getLogger(__name__)

#: Window bounds are multiples of this many cells (from the level's lower corner).
TILE_CELLS = 128
#: How many times a partial path widens its window (doubling the detour allowance).
PATH_RETRIES = 3
#: A level whose whole grid has more columns than this is built lazily (in "auto" mode).
LAZY_ABOVE_COLUMNS = 6_000_000


def full_columns(env, cell: float) -> int:
    """Columns of a whole-level grid at this cell size."""
    lo, hi = np.asarray(env.bounds, dtype=np.float64)
    return (int(math.ceil(min((hi[0] - lo[0]) / cell, 1e12)))
            * int(math.ceil(min((hi[2] - lo[2]) / cell, 1e12))))


def _current(name: str):
    """A read-only attribute of the current window's surface."""
    return property(lambda self: getattr(self.surface, name),
                    doc=f"The current window's surface's {name}.")


class LazyNav:
    """A NavSurface over a growing window of the level (a Navigation, see protocol.py).

    env, agent, cache_dir : as for navmesh.cache.load_or_build
    centre : (3,) world point the first window is centred on; half : metres, its half size
    """

    def __init__(self, env, agent, cache_dir, centre, half: float):
        self.env, self.agent, self.cache_dir = env, agent, cache_dir
        lo, hi = np.asarray(env.bounds, dtype=np.float64)
        self._level = (lo[[0, 2]], hi[[0, 2]])
        self._tile = TILE_CELLS * agent.cell_size
        self._margin = 4.0 * agent.radius + 2.0 * agent.cell_size
        c = np.asarray(centre, dtype=np.float64)[[0, 2]]
        self.windows: list[tuple[float, float, float, float]] = []
        self.cache_hits = 0
        self.surface: NavSurface
        # at most ~20 widenings: a window under a millionth of the level (an absurd rig) starts
        # at that size
        half = max(half, float(np.max(hi - lo)) * 2.0**-20)
        while True:  # a window with no walkable surface in it is widened until the level ends
            try:
                self._build(c - half, c + half)
                break
            except BudgetError:
                raise
            except NavError:
                if self._whole(c - half, c + half):
                    raise
                half *= 2.0

    # ------------------------------------------------------------------ the window
    @property
    def window(self) -> tuple[float, float, float, float]:
        """(x0, z0, x1, z1) of the current window, metres."""
        return self.windows[-1]

    def _snap(self, lo: np.ndarray, hi: np.ndarray):
        o, top = self._level
        t = self._tile
        lo = np.maximum(o + np.floor((lo - o) / t) * t, o)
        hi = np.minimum(o + np.ceil((hi - o) / t) * t, top)
        return lo, hi

    def _build(self, lo: np.ndarray, hi: np.ndarray) -> None:
        lo, hi = self._snap(lo, hi)
        bounds = np.array([lo, hi])
        self.surface, hit = load_or_build(self.env, self.agent, self.cache_dir, bounds=bounds)
        self.cache_hits += int(hit)
        self.windows.append((float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])))
        log.info("navigation window %s (%s)", self.window, "cache" if hit else "built")

    def _whole(self, lo, hi) -> bool:
        o, top = self._level
        return bool(np.all(np.asarray(lo) <= o) and np.all(np.asarray(hi) >= top))

    def covers(self, lo, hi) -> bool:
        """True when the window holds the box [lo, hi] (x, z) or the level ends there."""
        x0, z0, x1, z1 = self.window
        o, top = self._level
        lo = np.maximum(np.asarray(lo, dtype=np.float64), o)
        hi = np.minimum(np.asarray(hi, dtype=np.float64), top)
        return bool(lo[0] >= x0 and lo[1] >= z0 and hi[0] <= x1 and hi[1] <= z1)

    def ensure(self, lo, hi) -> bool:
        """Grow the window to hold the box [lo, hi] (x, z) plus a margin; True if it grew.
        A side that has to move moves by at least half the window's size."""
        lo = np.asarray(lo, dtype=np.float64) - self._margin
        hi = np.asarray(hi, dtype=np.float64) + self._margin
        if self.covers(lo, hi):
            return False
        x0, z0, x1, z1 = self.window
        wlo, whi = np.array([x0, z0]), np.array([x1, z1])
        grow = 0.5 * (whi - wlo)
        nlo = np.where(lo < wlo, np.minimum(lo, wlo - grow), wlo)
        nhi = np.where(hi > whi, np.maximum(hi, whi + grow), whi)
        self._build(nlo, nhi)
        return True

    def _around(self, p, r: float) -> None:
        q = np.asarray(p, dtype=np.float64).reshape(3)[[0, 2]]
        self.ensure(q - r, q + r)

    # ------------------------------------------------------------------ queries that reach out
    def nearest(self, p, max_dist: float = np.inf):
        self._around(p, 0.0)
        return self.surface.nearest(p, max_dist)

    def random_point_near(self, p, radius: float, rng):
        self._around(p, radius)
        return self.surface.random_point_near(p, radius, rng)

    def find_path(self, a, b):
        """The path on a window that holds both ends' box, widened by half their distance
        for detours; a partial path widens it (twice as much, up to PATH_RETRIES times)
        before it is given as the answer."""
        a3 = np.asarray(a, dtype=np.float64).reshape(3)
        b3 = np.asarray(b, dtype=np.float64).reshape(3)
        slack = 0.5 * float(np.hypot(*(b3 - a3)[[0, 2]])) + self._margin
        lo, hi = np.minimum(a3, b3)[[0, 2]], np.maximum(a3, b3)[[0, 2]]
        self.ensure(lo - slack, hi + slack)
        r = self.surface.find_path(a3, b3)
        for _ in range(PATH_RETRIES):
            if r.complete:
                break
            slack *= 2.0
            if self.ensure(lo - slack, hi + slack):   # else nothing new to search
                r = self.surface.find_path(a3, b3)
        return r

    # ------------------------------------------------------------------ queries on the window
    positions = _current("positions")
    component = _current("component")
    cell_size = _current("cell_size")
    agent_radius = _current("agent_radius")
    agent_height = _current("agent_height")
    step_height = _current("step_height")
    max_slope = _current("max_slope")

    def is_walkable(self, points, tol: float | None = None) -> np.ndarray:
        return self.surface.is_walkable(points, tol)

    def component_of(self, p) -> int:
        return self.surface.component_of(p)

    def surface_height(self, points, tol: float = np.inf) -> np.ndarray:
        return self.surface.surface_height(points, tol)

    def layer_height(self, x: float, y: float, z: float, tol: float) -> float:
        return self.surface.layer_height(x, y, z, tol)

    def resample_path(self, points, spacing: float | None = None) -> np.ndarray:
        return self.surface.resample_path(points, spacing)

    def segment_visible(self, a, b) -> bool:
        return self.surface.segment_visible(a, b)

    def stats(self) -> dict:
        s = self.surface.stats()
        s["lazy_windows"] = [[round(v, 6) for v in w] for w in self.windows]
        s["lazy_windows_from_cache"] = self.cache_hits
        return s

    def __getattr__(self, name):
        # everything else is the current surface's (only called for names not found above)
        if name == "surface":
            raise AttributeError(name)
        return getattr(self.surface, name)
