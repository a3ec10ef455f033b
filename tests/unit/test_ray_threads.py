"""environment.rays casts a large batch on several threads (Embree runs with the GIL released),
each into its own rows: the same bits as one thread, whatever the thread count."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from baker.environment import rays as rays_module
from baker.environment.rays import THREAD_MIN_RAYS, RayCaster


@pytest.fixture(scope="module")
def caster():
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    mesh.vertices += np.array([1000.0, 2.0, -500.0])       # far from the origin, as levels are
    return RayCaster(mesh)


def _rays(n: int, seed: int):
    rng = np.random.default_rng(seed)
    o = np.array([1000.0, 2.0, -500.0]) + rng.uniform(-1.5, 1.5, (n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o, d, rng.uniform(0.1, 3.0, n)


@pytest.mark.parametrize("threads", [2, 3, 8])
def test_threaded_casts_give_the_one_thread_bits(caster, monkeypatch, threads):
    n = 5 * THREAD_MIN_RAYS + 17
    o, d, dist = _rays(n, threads)
    monkeypatch.setattr(rays_module, "_threads", lambda: 1)
    one = (caster.cast(o, d), caster.cast(o, d, dist), caster.cast_uv(o, d))
    monkeypatch.setattr(rays_module, "_threads", lambda: threads)
    many = (caster.cast(o, d), caster.cast(o, d, dist), caster.cast_uv(o, d))
    for a, b in zip(one, many):
        for x, y in zip(a, b):
            assert x.tobytes() == y.tobytes()
    hit = one[0][1] >= 0
    assert 0.2 < hit.mean() < 1.0 and (one[1][1] >= 0).sum() < hit.sum()


def test_an_error_on_a_casting_thread_reaches_the_caller(caster, monkeypatch):
    n = 4 * THREAD_MIN_RAYS
    o, d, _ = _rays(n, 0)
    monkeypatch.setattr(rays_module, "_threads", lambda: 4)
    real = RayCaster._embree

    def failing(self, origins, directions, dist, uv, t, prim, start, stop):
        if start > 0:
            raise MemoryError("no room for the staging buffers")
        real(self, origins, directions, dist, uv, t, prim, start, stop)

    monkeypatch.setattr(RayCaster, "_embree", failing)
    with pytest.raises(MemoryError):
        caster.cast(o, d)


@pytest.mark.parametrize("threads", [1, 3])
@pytest.mark.parametrize("n", [5, 3 * THREAD_MIN_RAYS + 5])
def test_column_casts_are_the_bits_of_the_general_cast(caster, monkeypatch, threads, n):
    """cast_columns (the navigation build's downward rays, origins staged coordinate by
    coordinate, one shared direction) answers exactly as cast() with (n, 3) arrays, on one
    thread or several, in small and large batches; CHUNK_RAYS small enough to take several
    chunks a thread."""
    monkeypatch.setattr(rays_module, "_threads", lambda: threads)
    monkeypatch.setattr(rays_module, "CHUNK_RAYS", THREAD_MIN_RAYS // 2 + 3)
    rng = np.random.default_rng(n + threads)
    o = np.array([1000.0, 4.0, -500.0]) + rng.uniform(-1.5, 1.5, (n, 3))
    down = np.broadcast_to([0.0, -1.0, 0.0], o.shape)
    t, prim = caster.cast_columns(o[:, 0].copy(), o[:, 1].copy(), o[:, 2].copy())
    t0, prim0 = caster.cast(o, down)
    assert t.tobytes() == t0.tobytes() and prim.tobytes() == prim0.tobytes()
    if n > 100:
        assert 0.2 < (prim >= 0).mean() < 1.0
