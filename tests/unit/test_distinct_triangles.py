"""environment.model.distinct_triangles: a triangle repeated in place (a primitive or a mesh
copied, from any corner but wound the same way, with its own vertices or shared ones) is kept
once in the mesh the ray casts and the navigation build use; distinct triangles all stay, and so
does a copy wound the other way (a double-sided floor's two faces). A level of
one box repeated 200 times took 4 s and 0.9 GB to build its navigation (2000: past 300 s):
each copy was a layer of its own in every column."""

from __future__ import annotations

import numpy as np

from baker.environment.model import distinct_triangles
from baker.navmesh import build
from test_navmesh_scenes import AGENT, box, env_of, floor


def test_repeats_from_any_corner_are_dropped_the_first_and_other_windings_kept():
    rng = np.random.default_rng(5)
    v = rng.random((40, 3))
    f = rng.choice(40, size=(30, 3), replace=True)
    f = f[np.array([len(set(t)) == 3 for t in f])]
    copies = np.concatenate([v, v])                              # the same points again
    faces = np.concatenate([f, f + 40, np.roll(f, 1, axis=1), f[:, ::-1], f[:5],
                            np.roll(f[:, ::-1], 2, axis=1) + 40])
    got = distinct_triangles(copies, faces)
    assert np.array_equal(got, np.concatenate([f, f[:, ::-1]]))


def test_distinct_triangles_are_all_kept_and_returned_as_they_are():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1],
                  [0, 1e-12, 0]], dtype=np.float64)
    f = np.array([[0, 1, 2], [1, 3, 2], [4, 1, 2],               # 4: 1e-12 m off corner 0
                  [0, 2, 3]])
    assert distinct_triangles(v, f) is f
    one = f[:1]
    assert distinct_triangles(v, one) is one


def test_a_box_repeated_in_place_builds_the_navigation_of_one():
    once = env_of(floor(-0.5, 1.5, -0.5, 1.5), box((0.3, 0.0, 0.3), (0.7, 0.2, 0.7)))
    many = env_of(floor(-0.5, 1.5, -0.5, 1.5),
                  *[box((0.3, 0.0, 0.3), (0.7, 0.2, 0.7)) for _ in range(300)])
    assert len(many.mesh.faces) == len(once.mesh.faces)
    a, b = build(once, AGENT), build(many, AGENT)
    assert a.n_samples == b.n_samples and a.walkable_area == b.walkable_area


def test_copies_of_a_box_with_round_coordinates_are_found():
    """Corners such as (2, 0, -2), whose floats' low bits are all zero, hash apart as well
    (a hash of their bits multiplied without scrambling kept only the top bits, and 50 copies
    of such a box stayed 600 triangles)."""
    b = box((-2.0, -0.125, -2.0), (2.0, 0.0, 2.0))
    v = np.asarray(b.vertices, dtype=np.float64)
    f = np.asarray(b.faces, dtype=np.int64)
    vv = np.concatenate([v] * 50)
    ff = np.concatenate([f + k * len(v) for k in range(50)])
    assert np.array_equal(distinct_triangles(vv, ff), f)
