"""Property tests of the navigation queries (hypothesis)."""

from __future__ import annotations

import functools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from baker.navmesh import build
from test_navmesh_scenes import AGENT, CELL, box, env_of, floor, half_log, quad


@functools.lru_cache(maxsize=None)
def flat_scene():
    """Flat floor with a thin wall, a tall box and a raised platform (its own component)."""
    return build(env_of(
        floor(0.0, 1.2, 0.0, 1.2),
        quad((0.503, 0, 0), (0.503, 0.3, 0), (0.503, 0.3, 0.7), (0.503, 0, 0.7)),
        box((0.75, 0.0, 0.2), (0.95, 0.3, 0.4)),
        box((0.1, 0.0, 0.8), (0.4, 0.2, 1.1)),
    ), AGENT)


@functools.lru_cache(maxsize=None)
def log_scene():
    return build(env_of(floor(0.0, 1.0, -0.3, 1.3), half_log()), AGENT)


coord = st.floats(0.0, 1.2, allow_nan=False)
level = st.sampled_from([0.0, 0.2, 0.3])


def _start(s, x, y, z):
    return s.nearest([x, y, z])


@settings(max_examples=60, deadline=None)
@given(x=coord, y=level, z=coord, radius=st.floats(0.02, 1.0), seed=st.integers(0, 2**32 - 1))
def test_random_point_near_is_walkable_and_reachable(x, y, z, radius, seed):
    s = flat_scene()
    p = _start(s, x, y, z)
    assert p is not None and s.is_walkable(p[None])[0]
    rng = np.random.default_rng(seed)
    for _ in range(5):
        q = s.random_point_near(p, radius, rng)
        if q is None:
            continue
        assert np.linalg.norm(q - p) <= radius + 1e-9
        assert s.is_walkable(q[None], tol=1e-5)[0]
        assert s.component_of(q) == s.component_of(p)


def _assert_visible_by_sampling(s, a, b, comp):
    n = int(np.ceil(np.linalg.norm((b - a)[[0, 2]]) / (0.25 * CELL))) + 2
    t = np.linspace(0.0, 1.0, n)[:, None]
    pts = a + t * (b - a)
    assert s.is_walkable(pts, tol=1e-4).all()
    assert all(s.component_of(p) == comp for p in pts[:: max(1, n // 8)])


@settings(max_examples=60, deadline=None)
@given(ax=coord, az=coord, ay=level, bx=coord, bz=coord, by=level)
def test_find_path_points_are_mutually_visible(ax, az, ay, bx, bz, by):
    s = flat_scene()
    a = _start(s, ax, ay, az)
    r = s.find_path(a, [bx, by, bz])
    pts = r.points
    assert len(pts) >= 1
    assert np.allclose(pts[0], a)
    comp = s.component_of(a)
    for p, q in zip(pts[:-1], pts[1:]):
        assert s.segment_visible(p, q)
        _assert_visible_by_sampling(s, p, q, comp)
    if r.complete:
        assert s.component_of([bx, by, bz]) == comp
    else:
        assert s.component_of([bx, by, bz]) != comp


@settings(max_examples=40, deadline=None)
@given(ax=st.floats(0.0, 1.0), az=st.floats(-0.3, 1.3), ay=st.sampled_from([0.0, 0.2]),
       bx=st.floats(0.0, 1.0), bz=st.floats(-0.3, 1.3), by=st.sampled_from([0.0, 0.2]))
def test_find_path_on_curved_log(ax, az, ay, bx, bz, by):
    s = log_scene()
    a = s.nearest([ax, ay, az])
    r = s.find_path(a, [bx, by, bz])
    assert s.is_walkable(r.points, tol=1e-4).all()
    for p, q in zip(r.points[:-1], r.points[1:]):
        assert s.segment_visible(p, q)


@settings(max_examples=30, deadline=None)
@given(ax=st.floats(0.0, 1.0), az=st.floats(-0.3, 1.3), ay=st.sampled_from([0.0, 0.2]),
       bx=st.floats(0.0, 1.0), bz=st.floats(-0.3, 1.3), by=st.sampled_from([0.0, 0.2]))
def test_resampled_path_follows_the_surface(ax, az, ay, bx, bz, by):
    s = log_scene()
    a = s.nearest([ax, ay, az])
    r = s.find_path(a, [bx, by, bz])
    dense = s.resample_path(r.points, 0.02)
    assert np.allclose(dense[0], r.points[0]) and np.allclose(dense[-1], r.points[-1])
    assert s.is_walkable(dense, tol=1e-4).all()
    step = np.linalg.norm((dense[1:] - dense[:-1])[:, [0, 2]], axis=1)
    assert np.all(step <= 0.02 + 1e-9)
    # neighbouring dense points stay on one layer: no jumps larger than the step height
    assert np.all(np.abs(np.diff(dense[:, 1])) <= AGENT.step_height + 1e-9)
