"""Navigation surface: build (environment -> NavSurface) and queries (Recast/Detour split)."""

from baker.navmesh.build import build
from baker.navmesh.query import (
    component_of,
    find_path,
    is_walkable,
    nearest,
    random_point_near,
    resample_path,
    segment_visible,
    surface_height,
)
from baker.navmesh.surface import FORMAT_VERSION, NavSurface, PathResult

__all__ = [
    "FORMAT_VERSION", "NavSurface", "PathResult", "build", "component_of", "find_path",
    "is_walkable", "nearest", "random_point_near", "resample_path", "segment_visible", "surface_height",
]
