"""`baker navmesh ENV`: build (or load from the cache) the navigation surface of one environment,
summarise it, and optionally draw its top-down map with a path. The CLI only calls `run`."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from baker.atomic import atomic_output, check_writable
from baker.errors import ConfigError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class NavReport:
    """What `run` did.

    stats      : NavSurface.stats() plus largest_component_share (0..1)
    seconds    : wall time of the build (or of the cache load)
    cache_hit  : True when the surface came from the cache; None when caching is off
    cache_path : the cache file read or written; None when caching is off
    path       : PathResult for --from/--to (points in world coordinates), or None
    png        : the map written (axes in world coordinates), or None
    """

    environment: str
    stats: dict
    seconds: float
    cache_hit: bool | None
    cache_path: Path | None
    path: object = None
    png: Path | None = None


def run(environment, agent, cache_dir=None, *, png=None, path_from=None, path_to=None,
        surface_out: list | None = None, max_memory_mb: float | None = None,
        up_axis: str | None = None, units: str | None = None) -> NavReport:
    """Load `environment`, build its surface for `agent` (a NavAgentConfig) or load it from
    `cache_dir` (None: no cache), find the path from `path_from` to `path_to` ((3,) world points,
    both or neither; the surface itself is in the environment's local frame) and draw the map to
    `png` (needs matplotlib; axes in world coordinates).
    surface_out: optional list that receives the NavSurface (for callers and tests).
    max_memory_mb: refuse a build estimated over this many MB (None: half of the RAM).
    up_axis, units: the level's up axis ("y", "z") and unit ("cm", ...; None: the file's
    own), as `load_environment`."""
    from baker.environment import load_environment
    from baker.navmesh import cache as nav_cache

    if (path_from is None) != (path_to is None):
        raise ConfigError("--from and --to must be given together", where="command line")
    if png is not None:
        png = Path(png)
        if png.suffix.lower() != ".png":
            raise ConfigError(f"--png must name a .png file (got {png.name})", where="--png")
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise ConfigError("--png needs matplotlib: pip install 'baker[debug]'") from None
        if png.parent.exists() and not png.parent.is_dir():
            raise ConfigError(f"--png folder is not a folder: {png.parent}")
        from baker.atomic import is_special

        if is_special(png):       # (a FIFO there was renamed over)
            raise ConfigError(f"--png {png.name} is a device, pipe or socket, not a file",
                              where="--png")
    env = load_environment(Path(environment), up_axis=up_axis, units=units)
    t = time.perf_counter()
    from baker.navmesh.budget import memory_limit

    with memory_limit(max_memory_mb):
        surface, hit = nav_cache.load_or_build(env, agent, cache_dir)
    seconds = time.perf_counter() - t
    cpath = None if cache_dir is None else nav_cache.cache_path(cache_dir, env, agent)
    stats = surface.stats()
    total = float(np.sum(surface.component_area))
    stats["largest_component_share"] = (round(float(surface.component_area[0]) / total, 4)
                                        if total > 0 else 0.0)
    path = None
    if path_from is not None:   # world in and out; the surface is in the environment's frame
        path = surface.find_path(env.to_local(path_from), env.to_local(path_to))
    if png is not None:
        png = _draw(surface, png, path, Path(environment).name, env.origin)
    if path is not None:
        path = replace(path, points=env.to_world(path.points))
    if surface_out is not None:
        surface_out.append(surface)
    return NavReport(environment=str(environment), stats=stats, seconds=seconds,
                     cache_hit=None if cache_dir is None else hit, cache_path=cpath,
                     path=path, png=png)


def _draw(surface, png: Path, path, name: str, origin) -> Path:
    """Draw to a temporary file beside `png`, then rename (no half-written map)."""
    from baker.navmesh.debug import draw_map

    title = (f"{name}: walkable {surface.walkable_area:.2f} m^2, "
             f"{surface.n_components} components")
    check_writable(png.parent)
    with atomic_output(png) as tmp:
        draw_map(surface, tmp, paths=() if path is None else (path,), title=title, origin=origin)
    return png


def format_report(r: NavReport) -> str:
    """A few lines for the terminal."""
    s = r.stats
    a = s["agent"]
    lines = [
        f"{Path(r.environment).name}: {s['samples']:,} walkable samples, "
        f"{s['walkable_area_m2']:.2f} m^2 walkable, {s['components']} components "
        f"(largest {100.0 * s['largest_component_share']:.1f} %, {s['largest_component_m2']:.2f} m^2)",
        f"  grid {s['grid'][0]} x {s['grid'][1]} columns of {s['cell_size']:.4g} m; agent radius "
        f"{a['radius']:.4g} m, height {a['height']:.4g} m, step {a['step_height']:.4g} m, "
        f"max slope {np.degrees(a['max_slope']):.1f} deg",
    ]
    if r.cache_hit is None:
        lines.append(f"  built in {r.seconds:.2f} s (cache off)")
    elif r.cache_hit:
        lines.append(f"  loaded in {r.seconds:.2f} s (cache hit) from {r.cache_path}")
    else:
        lines.append(f"  built in {r.seconds:.2f} s (cache miss), cached at {r.cache_path}")
    if r.path is not None:
        p = r.path.points
        lines.append(f"  path {_xyz(p[0])} -> {_xyz(p[-1])}: {r.path.length:.2f} m, {len(p)} points, "
                     + ("complete" if r.path.complete else "PARTIAL (goal not reachable)"))
    if r.png is not None:
        lines.append(f"  map -> {r.png}")
    return "\n".join(lines)


def _xyz(p) -> str:
    return "(" + ", ".join(f"{float(x):.2f}" for x in p) + ")"
