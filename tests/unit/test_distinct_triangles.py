"""environment.model.distinct_triangles: a triangle repeated in place (a primitive or a mesh
copied, in any corner order or winding, with its own vertices or shared ones) is kept once in
the mesh the ray casts and the navigation build use; distinct triangles all stay. A level of
one box repeated 200 times took 4 s and 0.9 GB to build its navigation (2000: past 300 s):
each copy was a layer of its own in every column."""

from __future__ import annotations

import numpy as np

from baker.environment.model import distinct_triangles
from baker.navmesh import build
from test_navmesh_scenes import AGENT, box, env_of, floor


def test_repeats_in_any_order_or_winding_are_dropped_and_the_first_kept():
    rng = np.random.default_rng(5)
    v = rng.random((40, 3))
    f = rng.choice(40, size=(30, 3), replace=True)
    f = f[np.array([len(set(t)) == 3 for t in f])]
    copies = np.concatenate([v, v])                              # the same points again
    faces = np.concatenate([f, f[:, ::-1] + 40, np.roll(f, 1, axis=1), f[:5]])
    got = distinct_triangles(copies, faces)
    assert np.array_equal(got, f)


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
