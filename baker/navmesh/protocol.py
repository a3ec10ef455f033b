"""What the simulation asks of a navigation surface: the `Navigation` protocol.

Two classes satisfy it:
- query.NavSurface: queries over one built NavData (the whole level, or one window of it);
- lazy.LazyNav: a surface built lazily in growing windows of a big level; the queries that can
  reach beyond the window (nearest, random_point_near, find_path) grow it first, the others
  answer on the current window.

Callers (baker/run, baker/behaviour, baker/metrics, the report) type their `nav` as Navigation
and use nothing else, so either class stands in for the other. tests/unit/test_navmesh_protocol.py
checks that both classes provide every member with the same signature.

All positions are (3,) or (n, 3) world metres; expected failures (nothing near, an unreachable
goal) are results (None, NaN, complete=False), never exceptions.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:   # annotations only (never imported at run time: no import edge)
    from baker.navmesh.surface import PathResult


@runtime_checkable
class Navigation(Protocol):
    """A walkable surface the simulation can query (see the module docstring).

    Data attributes (of the surface answering now; a LazyNav's change as its window grows):
    positions (N, 3) float32 sample points, component (N,) int32 labels (0 = largest),
    cell_size, agent_radius, agent_height, step_height, max_slope (metres / radians).
    """

    positions: np.ndarray
    component: np.ndarray
    cell_size: float
    agent_radius: float
    agent_height: float
    step_height: float
    max_slope: float

    def nearest(self, p, max_dist: float = np.inf) -> np.ndarray | None:
        """(3,) closest walkable surface point to p (within max_dist, 3D), or None."""

    def random_point_near(self, p, radius: float, rng: np.random.Generator) -> np.ndarray | None:
        """(3,) random walkable point within `radius` (3D) of p, reachable from p, uniform by
        surface area; None when there is none."""

    def find_path(self, a, b) -> "PathResult":
        """Smoothed path from a to b on the surface; complete=False when b is unreachable."""

    def is_walkable(self, points, tol: float | None = None) -> np.ndarray:
        """(n,) bool: points within `tol` (vertically) of the walkable surface."""

    def component_of(self, p) -> int:
        """Component label of the sample nearest p, -1 when the surface is empty."""

    def surface_height(self, points, tol: float = np.inf) -> np.ndarray:
        """(n,) surface height under each point (the layer closest in height), NaN if none."""

    def layer_height(self, x: float, y: float, z: float, tol: float) -> float:
        """Scalar surface_height of one point (no retry on cell borders), NaN if none."""

    def resample_path(self, points, spacing: float | None = None) -> np.ndarray:
        """(m, 3) points along a path every `spacing` m, heights on the walked surface."""

    def segment_visible(self, a, b) -> bool:
        """True when the straight segment a-b stays on linked walkable samples of one layer."""

    def stats(self) -> dict:
        """Summary for reports (plain JSON types)."""
