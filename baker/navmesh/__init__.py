"""Navigation surface: build (environment -> NavData, Recast's side) and queries (NavSurface over
a NavData, Detour's side); the Navigation protocol is what the simulation uses (NavSurface and
the lazily built LazyNav both satisfy it)."""

from baker.navmesh.build import build
from baker.navmesh.protocol import Navigation
from baker.navmesh.query import (
    NavSurface,
    component_of,
    find_path,
    is_walkable,
    nearest,
    random_point_near,
    resample_path,
    segment_visible,
    surface_height,
)
from baker.navmesh.surface import FORMAT_VERSION, NavData, PathResult

__all__ = [
    "FORMAT_VERSION", "NavData", "NavSurface", "Navigation", "PathResult", "build", "component_of", "find_path",
    "is_walkable", "nearest", "random_point_near", "resample_path", "segment_visible", "surface_height",
]
