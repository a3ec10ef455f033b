"""The navigation build's column layers (baker.navmesh.raster): the triangles rasterized into
the grid's columns give what repeated downward rays through the column centres give, and
coincident surfaces are judged on all their crossings.
"""

from __future__ import annotations

import importlib
import itertools
import math

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from baker.navmesh import raster
from signal_stops import assert_signals_stop_cleanly
from test_navmesh_doorways import BASE
from test_navmesh_scenes import box, env_of, floor, quad

B = importlib.import_module("baker.navmesh.build")   # the module (the package exports build())
EPS = 1e-4


def ray_layers(env, x0, z0, nx, nz, cell, ytop, eps=EPS):
    """Reference: per column, rays straight down through the centre, each re-cast eps below
    the last hit, until they miss. {column: [y, ...]} top to bottom."""
    col = np.arange(nx * nz)
    oy = np.full(len(col), ytop)
    out = {}
    while len(col):
        ix, iz = np.divmod(col, nz)
        t, prim = env.rays.cast_columns(x0 + (ix + 0.5) * cell, oy, z0 + (iz + 0.5) * cell)
        h = prim >= 0
        col, y = col[h], oy[h] - t[h]
        for c, v in zip(col.tolist(), y.tolist()):
            out.setdefault(c, []).append(v)
        oy = y - eps
    return out


def raster_layers(env, x0, z0, nx, nz, cell, comp=None, eps=EPS, max_passes=256):
    """The build's layers: raster.Triangles.layers then raster.coincident, as
    {column: [y, ...]} of the layers' surfaces, and the raw result."""
    rays = env.rays
    tri = raster.Triangles(rays.vertices, rays.faces, x0, z0, cell, nx, nz)
    col, y, prim = tri.layers(0, nx * nz)
    comp = np.zeros(len(rays.faces), np.int64) if comp is None else comp
    col, y, prim, head = raster.coincident(col, y, prim, comp, rays.face_normals[:, 1],
                                           np.ones(len(comp), bool), eps, max_passes)
    out = {}
    for c, v in zip(col[head].tolist(), y[head].tolist()):
        out.setdefault(c, []).append(v)
    return out, (col, y, prim, head)


def tilted_box(rng, size) -> trimesh.Trimesh:
    b = trimesh.creation.box(rng.uniform(0.1, size, 3))
    b.apply_transform(np.block([[Rotation.random(random_state=rng).as_matrix(),
                                 rng.uniform(0.2, 1.8, (3, 1))], [np.zeros((1, 3)), 1.0]]))
    return b


@pytest.mark.parametrize("seed", range(6))
def test_layers_match_repeated_downward_rays(seed):
    """Tilted boxes, a bumpy terrain and loose triangles: every column has the same layers as
    the rays find, at the same heights (to the rays' float32 precision)."""
    rng = np.random.default_rng(seed)
    g = np.linspace(0.0, 2.0, 9)
    gx, gz = np.meshgrid(g, g, indexing="ij")
    verts = np.c_[gx.ravel(), rng.uniform(-0.1, 0.1, gx.size), gz.ravel()]
    faces = []
    for i in range(8):
        for k in range(8):
            a, b, c, d = i * 9 + k, i * 9 + k + 1, (i + 1) * 9 + k + 1, (i + 1) * 9 + k
            faces += [[a, b, c], [a, c, d]]
    terrain = trimesh.Trimesh(verts, faces, process=False)
    loose = trimesh.Trimesh(rng.uniform(0.0, 2.0, (30, 3)), np.arange(30).reshape(10, 3),
                            process=False)
    env = env_of(terrain, loose, *[tilted_box(rng, 0.8) for _ in range(6)])
    cell = 0.037
    x0, z0, nx, nz, ytop = B._grid(env, None, cell)
    want = ray_layers(env, x0, z0, nx, nz, cell, ytop)
    got, _ = raster_layers(env, x0, z0, nx, nz, cell)
    assert sum(map(len, want.values())) > 5000
    assert set(got) == set(want)
    for c, ys in want.items():
        assert len(got[c]) == len(ys), c
        np.testing.assert_allclose(got[c], ys, atol=2e-5)


def test_a_column_through_shared_edges_and_corners_finds_one_layer():
    """Column centres on the diagonals of a quad and on a vertex where eight triangles meet:
    every centre finds exactly one layer (no crack, no double)."""
    c = 0.1
    centre = np.array([0.25, 0.2, 0.75])                   # a column centre
    ring = [centre + 0.3 * np.array([math.cos(a), 0.0, math.sin(a)])
            for a in np.linspace(0.0, 2 * math.pi, 9)[:-1]]
    fan_mesh = trimesh.Trimesh(np.array([centre] + ring),
                               [[0, 1 + k, 1 + (k + 1) % 8] for k in range(8)], process=False)
    env = env_of(quad((0, 0, 0), (0, 0, 1), (1, 0, 1), (1, 0, 0)),   # diagonal x = z
                 fan_mesh)
    x0, z0, nx, nz, ytop = 0.0, 0.0, 10, 10, 1.0
    got, (col, y, prim, head) = raster_layers(env, x0, z0, nx, nz, c)
    assert len(got) == 100
    for k in range(10):                                  # centres (k + .5) c on the diagonal
        assert len(got[k * nz + k]) == 1
        assert (col == k * nz + k).sum() == 1           # the edge's two hits are one layer
    hub = 2 * nz + 7
    assert len(got[hub]) == 2 and got[hub][0] == pytest.approx(0.2)
    assert (col == hub).sum() == 2                        # the fan's eight hits: one
    spoke = 3 * nz + 7                                    # on the fan's edge along +x
    assert len(got[spoke]) == 2 and (col == spoke).sum() == 2


def test_vertical_triangles_are_not_hit_and_layers_stop_at_max_passes():
    wall = quad((0.5, 0, 0), (0.5, 0, 1), (0.5, 1, 1), (0.5, 1, 0))  # the plane x = 0.5
    stack = [floor(0, 1, 0, 1, y=0.1 * k) for k in range(5)]
    env = env_of(wall, *stack)
    got, _ = raster_layers(env, 0.0, 0.0, 20, 20, 0.05)     # centres at x = 0.475, 0.525
    assert all(len(v) == 5 for v in got.values()) and len(got) == 400
    got, _ = raster_layers(env, 0.0, 0.0, 20, 20, 0.05, max_passes=3)
    assert all(v == pytest.approx([0.4, 0.3, 0.2]) for v in got.values())


def test_coincident_layers_keep_every_solids_crossings():
    """A wall standing on a slab, carrying another: its foot and its top each coincide with a
    slab's face. Each layer keeps one crossing per solid and side, and the flattest surface
    leads it; the inside test sees the wall's crossings."""
    env = env_of(box((0, -0.1, 0), (1, 0, 1)), box((0.4, 0, 0), (0.6, 0.5, 1)),
                 box((0, 0.5, 0), (1, 0.6, 1)))
    comp = np.repeat(np.arange(3), 12)
    got, (col, y, prim, head) = raster_layers(env, 0.0, 0.0, 20, 20, 0.05, comp=comp)
    c = 10 * 20 + 10                                    # inside the wall's footprint
    here = col == c
    assert got[c] == pytest.approx([0.6, 0.5, 0.0, -0.1])
    # 0.5: the upper slab's underside and the wall's top; 0.0: the wall's foot and the slab
    assert sorted(comp[prim[here]].tolist()) == [0, 0, 1, 1, 2, 2]
    c = 2 * 20 + 2                                      # beside the wall
    assert got[c] == pytest.approx([0.6, 0.5, 0.0, -0.1])
    assert (col == c).sum() == 4


@pytest.mark.parametrize("order", list(itertools.permutations(range(3))))
def test_the_floor_under_a_wall_between_two_slabs_is_not_walkable(order):
    """A wall resting on the floor slab and carrying the next storey's slab: its foot and its
    top both coincide with a slab's face. The rays found one hit of each pair, and when they
    missed both of the wall's, its inside was floor (136 samples in the listing order
    floor, wall, slab)."""
    s = 1.0 / 8.0  # the doorway scenes' scale: sizes for the 2 m rig, for the 0.25 m rig
    parts = [box((0, -0.2 * s, 0), (6 * s, 0, 4 * s)), box((2 * s, 0, 0), (4 * s, 2.5 * s, 4 * s)),
             box((0, 2.5 * s, 0), (6 * s, 2.7 * s, 4 * s))]
    nav = B.build(env_of(*[parts[i] for i in order]), BASE)
    p = np.asarray(nav.data.positions)
    p = p[np.abs(p[:, 1]) < 1e-3]                         # the floor (the roof is walkable too)
    cell = BASE.cell_size
    assert not ((p[:, 0] > 2 * s + cell) & (p[:, 0] < 4 * s - cell)).any()
    assert (p[:, 0] < 2 * s).sum() > 100 and (p[:, 0] > 4 * s).sum() > 100


def test_signals_during_the_compiled_layers_stop_cleanly():
    """A signal whose handler raises (baker.signals stops a bake so) while numba boxes a
    compiled function's result crashed the process (numba's dispatcher returned with the
    exception set): the compiled calls run off the main thread. 20 SIGTERMs at staggered
    moments during repeated calls, each raising in the main thread."""
    assert_signals_stop_cleanly("""
        from baker.navmesh import raster
        rng = np.random.default_rng(0)
        c = rng.uniform(0, 100, (100000, 1, 3))
        v = (c + rng.uniform(-0.3, 0.3, (100000, 3, 3))).reshape(-1, 3)
        f = np.arange(len(v)).reshape(-1, 3)
        tri = raster.Triangles(v, f, 0.0, 0.0, 0.05, 2000, 2000)
        comp, ny, wound = np.zeros(len(f), np.int64), np.ones(len(f)), np.ones(len(f), bool)
        """, """
        col, y, prim = tri.layers(0, 2000 * 2000)
        raster.coincident(col, y, prim, comp, ny, wound, 1e-4, 256)
        """)
