"""The lazily built navigation surface (navmesh/lazy.py): windows that grow where queries reach,
on scenes built in code with the default rig's agent (radius 0.02 m, cell 0.015 m)."""

from __future__ import annotations

import numpy as np
import pytest

from baker.config import DEFAULT_RIG, load_rig_config
from baker.navmesh import build
from baker.navmesh.lazy import TILE_CELLS, LazyNav, full_columns
from test_navmesh_scenes import box, env_of, floor, quad

AGENT = load_rig_config(DEFAULT_RIG).navigation
TILE = TILE_CELLS * AGENT.cell_size


@pytest.fixture(scope="module")
def field():
    """A 12 x 12 m floor with a row of blocks across it at x = 2 (a gap at z > 4)."""
    return env_of(floor(-6.0, 6.0, -6.0, 6.0), box((2.0, 0.0, -6.0), (2.3, 0.2, 4.0)))


def test_first_window_is_snapped_and_small(field):
    nav = LazyNav(field, AGENT, None, centre=(0.0, 0.0, 0.0), half=1.0)
    x0, z0, x1, z1 = nav.window
    for v in (x0, z0, x1, z1):  # on the tile grid from the level's corner (or its edge)
        k = (v + 6.0) / TILE
        assert abs(k - round(k)) < 1e-9 or abs(abs(v) - 6.0) < 1e-9
    assert x0 <= -1.0 and x1 >= 1.0 and (x1 - x0) < 12.0
    assert nav.n_samples < full_columns(field, AGENT.cell_size)
    assert len(nav.windows) == 1


def test_queries_beyond_the_window_grow_it(field):
    nav = LazyNav(field, AGENT, None, centre=(0.0, 0.0, 0.0), half=1.0)
    w0 = nav.window
    rng = np.random.default_rng(0)
    p = nav.random_point_near([0.0, 0.0, 0.0], 3.0, rng)  # a disc wider than the window
    assert len(nav.windows) == 2
    x0, z0, x1, z1 = nav.window
    assert x0 <= -3.0 and z0 <= -3.0 and x1 >= 3.0 and z1 >= 3.0
    assert p is not None and nav.is_walkable(p[None])[0]
    # a path across the blocks: they reach z = 4, so the corridor widens around them
    r = nav.find_path([0.5, 0.0, 0.0], [4.0, 0.0, 0.0])
    assert r.complete
    assert r.points[:, 2].max() > 4.0   # around the end of the row of blocks
    assert nav.is_walkable(r.points).all()
    # windows only grow, and each growth moves a side by at least half the window
    for a, b in zip(nav.windows, nav.windows[1:]):
        assert b[0] <= a[0] and b[1] <= a[1] and b[2] >= a[2] and b[3] >= a[3]
        grew = np.array([a[0] - b[0], a[1] - b[1], b[2] - a[2], b[3] - a[3]])
        size = np.array([a[2] - a[0], a[3] - a[1]] * 2)
        assert np.any(grew >= 0.5 * size - TILE - 1e-9)
    assert nav.window != w0


def test_inside_the_window_it_is_the_full_surface(field):
    """Away from the window's edge, the lazy surface and the whole-level build agree."""
    nav = LazyNav(field, AGENT, None, centre=(0.0, 0.0, 0.0), half=2.0)
    full = build(field, AGENT)
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(-1.5, 1.5, 300), np.zeros(300), rng.uniform(-1.5, 1.5, 300)])
    assert np.array_equal(nav.is_walkable(pts), full.is_walkable(pts))
    assert np.allclose(nav.surface_height(pts), full.surface_height(pts), equal_nan=True)


def test_cached_windows_are_reused(field, tmp_path):
    a = LazyNav(field, AGENT, tmp_path, centre=(0.0, 0.0, 0.0), half=1.0)
    a.random_point_near([0.0, 0.0, 0.0], 3.0, np.random.default_rng(0))
    b = LazyNav(field, AGENT, tmp_path, centre=(0.0, 0.0, 0.0), half=1.0)
    b.random_point_near([0.0, 0.0, 0.0], 3.0, np.random.default_rng(0))
    assert a.cache_hits == 0 and b.cache_hits == 2
    assert a.windows == b.windows
    assert np.array_equal(a.positions, b.positions)


def test_a_first_window_with_nothing_walkable_widens():
    """The start's surroundings are a pond (no floor): the window widens until it finds the
    shore; a level with no walkable surface at all still raises."""
    from baker.errors import NavError

    env = env_of(floor(-6.0, 6.0, -6.0, -3.0), floor(-6.0, 6.0, 3.0, 6.0), floor(-6.0, -5.9, -6.0, 6.0))
    nav = LazyNav(env, AGENT, None, centre=(0.0, 0.0, 0.0), half=1.0)
    assert nav.n_samples > 0
    x0, z0, x1, z1 = nav.window
    assert z0 <= -3.0 or z1 >= 3.0
    steep = env_of(quad((0, 0, 0), (0, 1, 0), (0, 1, 1), (0, 0, 1)),
                   quad((5, 0, 0), (5, 1, 0), (5, 1, 1), (5, 0, 1)))
    with pytest.raises(NavError, match="no walkable surface"):
        LazyNav(steep, AGENT, None, centre=(2.5, 0.0, 0.5), half=0.5)
