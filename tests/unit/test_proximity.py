"""Exact point-to-mesh distances (geometry/proximity.py) and the inside test of the ray caster."""

from __future__ import annotations

import numpy as np
import trimesh
from hypothesis import example, given, settings
from hypothesis import strategies as st

from baker.environment.rays import RayCaster
from baker.geometry.proximity import TriangleSet


def brute_force(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(n,) distance to the nearest of the triangles (m, 3, 3), one triangle at a time
    (trimesh's closest point on a triangle as the reference)."""
    best = np.full(len(points), np.inf)
    for t in tri:
        q = trimesh.triangles.closest_point(np.broadcast_to(t, (len(points), 3, 3)), points)
        best = np.minimum(best, np.linalg.norm(q - points, axis=1))
    return best


def test_closest_point_on_a_triangle_is_never_beaten_by_a_dense_sample():
    rng = np.random.default_rng(3)
    u, v = np.meshgrid(np.linspace(0, 1, 201), np.linspace(0, 1, 201))
    keep = u + v <= 1
    u, v = u[keep], v[keep]
    for _ in range(100):
        a, b, c = rng.normal(size=(3, 3))
        p = rng.normal(size=3) * 2
        d, q, face = TriangleSet(np.stack([a, b, c]), [[0, 1, 2]]).closest(p[None], 100.0)
        dense = a + np.outer(u, b - a) + np.outer(v, c - a)
        assert face[0] == 0 and abs(np.linalg.norm(q[0] - p) - d[0]) < 1e-12
        assert d[0] <= np.linalg.norm(dense - p, axis=1).min() + 1e-12


def test_degenerate_triangles_and_empty_queries():
    """A triangle collapsed to a segment or a point is measured as one; no points, no faces."""
    v = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [5, 5, 5]])
    d, q, face = TriangleSet(v, [[0, 1, 2], [3, 3, 3]]).closest(
        np.array([[1.0, 1.0, 0.0], [5.0, 5.0, 5.5], [9.0, 9.0, 9.0]]), 2.0)
    np.testing.assert_allclose(d[:2], [1.0, 0.5], atol=1e-12)
    assert face.tolist() == [0, 1, -1] and np.isinf(d[2]) and np.isnan(q[2]).all()
    assert len(TriangleSet(v, [[0, 1, 2]]).closest(np.zeros((0, 3)), 1.0)[0]) == 0
    assert np.isinf(TriangleSet(v, np.zeros((0, 3), int)).closest(np.zeros((2, 3)), 1.0)[0]).all()


@settings(max_examples=25)
@given(seed=st.integers(0, 2**31 - 1), cap=st.floats(0.01, 1.0), big=st.floats(1.0, 20.0))
@example(seed=0, cap=0.3, big=3.0)
def test_triangle_set_matches_brute_force_within_the_cap(seed, cap, big):
    """Mixed triangle sizes (a sphere with a few vertices pulled far out, like a level's big
    floor quads among small props): every distance within the cap is exact, the rest inf."""
    rng = np.random.default_rng(seed)
    m = trimesh.creation.icosphere(2)
    v = m.vertices.copy()
    v[rng.choice(len(v), 6, replace=False)] *= big
    pts = rng.normal(size=(300, 3)) * 1.5
    d, c, face = TriangleSet(v, m.faces).closest(pts, cap)
    ref = brute_force(pts, v[m.faces])
    within = ref <= cap
    assert np.all(np.isinf(d[~within]))
    np.testing.assert_allclose(d[within], ref[within], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(c[within] - pts[within], axis=1), d[within],
                               atol=1e-12)
    assert np.all(face[within] >= 0) and np.all(face[~within] == -1)


def test_inside_tells_solids_from_open_space():
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    ground = trimesh.Trimesh([[-5, -2, -5], [5, -2, -5], [5, -2, 5], [-5, -2, 5]],
                             [[0, 2, 1], [0, 3, 2]], process=False)      # up-facing, one-sided
    rays = RayCaster(trimesh.util.concatenate([box, ground]))
    pts = np.array([[0, 0, 0], [0.45, 0.45, -0.45], [0, 0.6, 0], [2, 0, 0], [0, -2.5, 0],
                    [0, -1.5, 3]])
    assert rays.inside(pts).tolist() == [True, True, False, False, True, False]
