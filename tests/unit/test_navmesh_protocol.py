"""Navigation as data (issue 15): the arrays (NavData) are apart from the query object
(NavSurface), and NavSurface and the lazily built LazyNav both satisfy the Navigation protocol
with the same signatures, answering alike inside a window."""

from __future__ import annotations

import inspect
import pickle

import numpy as np
import pytest

from baker.config import DEFAULT_RIG, load_rig_config
from baker.navmesh import NavData, Navigation, NavSurface, build
from baker.navmesh.build import build_data
from baker.navmesh.lazy import LazyNav
from test_navmesh_scenes import box, env_of, floor

AGENT = load_rig_config(DEFAULT_RIG).navigation
MEMBERS = [n for n in Navigation.__annotations__] + [
    n for n, v in vars(Navigation).items() if callable(v) and not n.startswith("_")]


@pytest.fixture(scope="module")
def scene():
    return env_of(floor(-2.0, 2.0, -2.0, 2.0), box((0.5, 0.0, -2.0), (0.7, 0.1, 1.0)))


def test_data_is_plain_arrays(scene):
    d = build_data(scene, AGENT)
    assert isinstance(d, NavData)
    for name, v in d.arrays().items():   # nothing but arrays and scalars: what the cache stores
        assert isinstance(v, (np.ndarray, tuple, float, int)), name
    assert not any(callable(getattr(d, m, None)) for m in ("find_path", "nearest"))
    s = NavSurface(d)
    assert s.positions is d.positions and s.links is d.links   # the same arrays, not copies
    assert s.stats() == d.stats()


def test_both_satisfy_the_protocol_with_the_same_signatures(scene):
    s = build(scene, AGENT)
    lazy = LazyNav(scene, AGENT, None, centre=(0.0, 0.0, 0.0), half=1.0)
    assert isinstance(s, Navigation) and isinstance(lazy, Navigation)
    for name in MEMBERS:
        assert hasattr(s, name) and hasattr(lazy, name), name
        proto = getattr(Navigation, name, None)
        if callable(proto):
            want = list(inspect.signature(proto).parameters)
            for cls in (NavSurface, LazyNav):
                got = list(inspect.signature(getattr(cls, name)).parameters)
                assert got == want, (cls.__name__, name, got)


def test_lazy_answers_as_the_surface_of_its_window(scene):
    lazy = LazyNav(scene, AGENT, None, centre=(0.0, 0.0, 0.0), half=1.0)
    s = lazy.surface
    pts = np.array([[0.1, 0.0, 0.1], [-0.3, 0.02, 0.2], [0.6, 0.1, -0.5]])
    assert np.array_equal(lazy.is_walkable(pts), s.is_walkable(pts))
    assert np.array_equal(lazy.surface_height(pts), s.surface_height(pts), equal_nan=True)
    assert lazy.component_of(pts[0]) == s.component_of(pts[0])
    assert lazy.layer_height(0.1, 0.0, 0.1, 0.05) == s.layer_height(0.1, 0.0, 0.1, 0.05)
    assert lazy.segment_visible(pts[0], pts[1]) == s.segment_visible(pts[0], pts[1])
    assert lazy.positions is s.positions and lazy.cell_size == s.cell_size


def test_query_object_pickles_as_its_data(scene):
    s = build(scene, AGENT).prepare()
    back = pickle.loads(pickle.dumps(s))
    assert isinstance(back, NavSurface) and back._cache == {}
    for k, v in s.arrays().items():
        assert np.array_equal(np.asarray(back.arrays()[k]), np.asarray(v))
    a, b = [-1.5, 0.0, 0.0], [1.5, 0.0, 1.5]
    assert np.array_equal(back.find_path(a, b).points, s.find_path(a, b).points)
