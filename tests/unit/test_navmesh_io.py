"""Navigation surface: cache, pickling, debug outputs and query edge cases."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from baker.config import NavAgentConfig
from baker.navmesh import build, cache, debug
from test_navmesh_scenes import AGENT, box, bridge_scene, env_of, floor


@pytest.fixture(scope="module")
def surface():
    return build(bridge_scene(), AGENT)


def _same(a, b):
    for k, v in a.arrays().items():
        w = b.arrays()[k]
        if isinstance(v, np.ndarray):
            assert np.array_equal(v, w), k
        else:
            assert v == w, k


def test_cache_roundtrip(tmp_path):
    env = bridge_scene()
    s1, hit1 = cache.load_or_build(env, AGENT, tmp_path)
    s2, hit2 = cache.load_or_build(env, AGENT, tmp_path)
    assert (hit1, hit2) == (False, True)
    _same(s1, s2)
    r1, r2 = s1.find_path([0.05, 0, 0.5], [0.95, 0, 0.5]), s2.find_path([0.05, 0, 0.5],
                                                                        [0.95, 0, 0.5])
    assert np.array_equal(r1.points, r2.points)
    # another agent is another key; no temporary files are left behind
    other = NavAgentConfig(radius=0.04, height=0.1, step_height=0.05, cell_size=0.01)
    assert cache.cache_path(tmp_path, env, AGENT) != cache.cache_path(tmp_path, env, other)
    assert [p.suffix for p in tmp_path.iterdir()] == [".npz"]


def test_cache_ignores_corrupt_file(tmp_path):
    env = bridge_scene()
    p = cache.cache_path(tmp_path, env, AGENT)
    p.write_bytes(b"not a zip")
    assert cache.load(p) is None
    s, hit = cache.load_or_build(env, AGENT, tmp_path)
    assert not hit and cache.load(p) is not None


def test_pickle(surface):
    s2 = pickle.loads(pickle.dumps(surface))
    _same(surface, s2)
    assert s2.nearest([0.5, 0.31, 0.5]) is not None


def test_walkable_mesh(surface):
    v, f = debug.walkable_mesh(surface)
    assert v.shape == (4 * surface.n_samples, 3) and f.shape == (2 * surface.n_samples, 3)
    assert f.max() < len(v)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert np.all(n[:, 1] > 0)  # faces point up


def test_draw_map(surface, tmp_path):
    pytest.importorskip("matplotlib")
    r = surface.find_path([0.05, 0, 0.5], [0.95, 0, 0.5])
    out = debug.draw_map(surface, tmp_path / "map.png", paths=[r], points=[[0.5, 0.3, 0.5]])
    assert out.stat().st_size > 1000


def test_nearest_and_edge_cases(surface):
    assert surface.nearest([5.0, 0.0, 5.0], max_dist=0.1) is None
    far = surface.nearest([5.0, 0.0, 5.0])
    assert far is not None and surface.is_walkable(far[None])[0]
    rng = np.random.default_rng(0)
    assert surface.random_point_near([5.0, 0.0, 5.0], 0.1, rng) is None
    r = surface.find_path([0.5, 0.3, 0.5], [0.5, 0.3, 0.5])
    assert r.complete and len(r.points) == 1
    assert not surface.is_walkable([[0.5, 0.15, 0.5]])[0]
    assert np.isnan(surface.surface_height([[5.0, 0.0, 5.0]])[0])


def test_random_point_near_is_uniform_by_area():
    s = build(env_of(floor(0.0, 1.0, 0.0, 1.0)), AGENT)
    rng = np.random.default_rng(3)
    q = np.array([s.random_point_near([0.5, 0.0, 0.5], 0.3, rng) for _ in range(4000)])
    d = np.hypot(q[:, 0] - 0.5, q[:, 2] - 0.5)
    assert d.max() <= 0.3
    # uniform on a disc: P(d < r/sqrt(2)) = 1/2
    assert abs(np.mean(d < 0.3 / np.sqrt(2)) - 0.5) < 0.04


def test_bounds_limit_the_build():
    env = env_of(floor(0.0, 1.0, 0.0, 1.0), box((0.6, 0, 0.6), (0.8, 0.3, 0.8)))
    s = build(env, AGENT, bounds=[[0.0, 0.0], [0.5, 0.5]])
    assert s.positions[:, 0].max() < 0.5 and s.positions[:, 2].max() < 0.5


def test_nearest_from_far_away_and_stats(surface):
    # far above / beside the scene: still the exact nearest surface point
    q = surface.nearest([0.5, 3.0, 0.5])
    assert abs(q[1] - 0.3) < 1e-6
    q = surface.nearest([3.0, 0.0, 0.5])
    assert abs(q[0] - 0.945) < 1e-6 and abs(q[1]) < 1e-6  # road end, eroded by r
    brute = surface.positions[np.argmin(np.linalg.norm(surface.positions - [3.0, 0.0, 0.5],
                                                       axis=1))]
    assert np.linalg.norm(q - [3, 0, 0.5]) <= np.linalg.norm(brute - [3, 0, 0.5]) + 1e-9
    st = surface.stats()
    assert st["samples"] == surface.n_samples and st["components"] == 2
    import json

    json.dumps(st)


def test_grid_too_large_is_a_nav_error(monkeypatch):
    import importlib

    from baker.errors import NavError

    build_mod = importlib.import_module("baker.navmesh.build")  # the module, not the function

    monkeypatch.setattr(build_mod, "MAX_COLUMNS", 1000)
    with pytest.raises(NavError, match="too large"):
        build_mod.build(env_of(floor()), AGENT)


def test_prepare_and_queries_agree(surface):
    import copy

    s2 = copy.deepcopy(surface).prepare()
    a, b = [0.05, 0, 0.5], [0.95, 0, 0.5]
    assert np.array_equal(s2.find_path(a, b).points, surface.find_path(a, b).points)


def test_build_log_message_formats(caplog):
    import logging

    with caplog.at_level(logging.INFO, logger="baker.navmesh.build"):
        build(bridge_scene(), AGENT)
    msgs = [r.getMessage() for r in caplog.records if r.name == "baker.navmesh.build"]
    assert any("walkable samples" in m for m in msgs)
