"""Doorways join rooms (issue 10), and solids that rest on each other (coincident faces).

The scene: two rooms side by side, floor continuous at one height through an open doorway in
the wall between them, an arch (or a flat lintel) over the doorway, and an upper floor's slab
resting on the walls and on the wall over the doorway, as level kits build them. Sizes are for
the 2 m rig (the default rig at --scale 8), and the whole scene is scaled by 1/8 for the default
0.25 m rig. Every solid is a closed, outward-wound box or prism (flip=True winds them all
inward).

Two coincident faces (the slab's underside on the lintel's top, a wall's foot on the floor)
give one ray hit, not two. The build used to count hits per closed solid down each column to
tell entering from leaving, so a lost hit left every hit below it "inside a solid": the floor
under every lintel that carried a slab was dropped, and the rooms fell apart at each doorway.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import trimesh

from baker.config import DEFAULT_RIG, load_rig_config, scale_rig
from baker.navmesh import build
from test_navmesh_scenes import box, env_of, floor

BASE = load_rig_config(DEFAULT_RIG).navigation
GIANT = scale_rig(load_rig_config(DEFAULT_RIG), 8.0).navigation


def arch_wall(x0, x1, z0, z1, zd0, zd1, spring, top, n=12) -> trimesh.Trimesh:
    """A wall across x in [x0, x1] (thickness), along z from z0 to z1, from y = 0 to `top`, with
    a doorway from the floor between zd0 and zd1 closed by a round arch springing at `spring`
    (n segments; n = 0: a flat lintel at `spring`). One closed prism, wound outward."""
    r, zc = 0.5 * (zd1 - zd0), 0.5 * (zd0 + zd1)
    if n:
        th = np.linspace(math.pi, 0.0, n + 1)
        arch = [(zc + r * math.cos(t), spring + r * math.sin(t)) for t in th]
    else:
        arch = [(zd0, spring), (zd1, spring)]
    poly = np.array([(z0, 0.0), (zd0, 0.0)] + arch + [(zd1, 0.0), (z1, 0.0), (z1, top),
                                                      (z0, top)])  # (z, y), counter-clockwise
    m = len(poly)
    # fan triangulation is wrong for this concave outline: clip ears
    tris, idx = [], list(range(m))
    cross = lambda a, b, c: (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])  # noqa
    while len(idx) > 3:
        for k in range(len(idx)):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            a, b, c = poly[i0], poly[i1], poly[i2]
            if cross(a, b, c) <= 1e-12:
                continue
            if any(cross(a, b, poly[j]) >= 0 and cross(b, c, poly[j]) >= 0
                   and cross(c, a, poly[j]) >= 0 for j in idx if j not in (i0, i1, i2)):
                continue
            tris.append((i0, i1, i2))
            idx.pop(k)
            break
    tris.append(tuple(idx))
    t = np.array(tris)
    v = np.concatenate([np.stack([np.full(m, x), poly[:, 1], poly[:, 0]], 1) for x in (x0, x1)])
    i = np.arange(m)
    j = (i + 1) % m
    f = np.concatenate([t, t[:, ::-1] + m, np.stack([i, j + m, j], 1),
                        np.stack([i, i + m, j + m], 1)])
    mesh = trimesh.Trimesh(v, f, process=False)
    if mesh.volume < 0:
        mesh.invert()
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    return mesh


def two_rooms(k: float = 1.0, top: str = "arch", slab: bool = True, flip: bool = False):
    """Rooms x in [0, 6] and [6, 12], z in [0, 6] (metres times k); walls 0.3 thick and 3.3
    high on a closed floor slab; a 1.6 m doorway at z 2.2..3.8 in the wall at x = 6 (arch
    springing at 2.2, crown 3.0; or a lintel at 2.6); with slab=True an upper floor (3.3..3.6)
    rests on all walls."""
    s = lambda *p: tuple(k * c for c in p)  # noqa: E731
    n = 12 if top == "arch" else 0
    spring = 2.2 if top == "arch" else 2.6
    meshes = [box(s(-1, -0.3, -1), s(13, 0, 7)),
              box(s(-0.15, 0, -0.15), s(12.15, 3.3, 0.15)),      # north
              box(s(-0.15, 0, 5.85), s(12.15, 3.3, 6.15)),       # south
              box(s(-0.15, 0, 0.1), s(0.15, 3.3, 5.9)),          # west
              box(s(11.85, 0, 0.1), s(12.15, 3.3, 5.9)),         # east
              arch_wall(k * 5.85, k * 6.15, k * 0.1, k * 5.9, k * 2.2, k * 3.8, k * spring,
                        k * 3.3, n)]
    if slab:
        meshes.append(box(s(-0.25, 3.3, -0.25), s(12.25, 3.6, 6.25)))
    return env_of(*meshes, flip=flip)


@pytest.mark.parametrize("flip", [False, True])
@pytest.mark.parametrize("top", ["arch", "lintel"])
@pytest.mark.parametrize("rig", ["giant", "default"])
def test_doorway_joins_two_rooms(rig, top, flip):
    k, agent = (1.0, GIANT) if rig == "giant" else (1.0 / 8.0, BASE)
    s = build(two_rooms(k, top, flip=flip), agent)
    a, b = s.component_of([3 * k, 0, 3 * k]), s.component_of([9 * k, 0, 3 * k])
    assert a == b >= 0
    door = np.array([[6 * k, 0.0, 3 * k]])
    assert s.is_walkable(door)[0]
    r = s.find_path([3 * k, 0, 3 * k], [9 * k, 0, 3 * k])
    assert r.complete and r.length < 6.5 * k
    assert np.all(np.abs(r.points[:, 1]) < 1e-6)
    # the slab's top is the upper floor: walkable, a separate component (no stairs here)
    assert s.is_walkable([[3 * k, 3.6 * k, 3 * k]])[0]
    assert s.component_of([3 * k, 3.6 * k, 3 * k]) != a


def test_doorway_without_upper_floor():
    s = build(two_rooms(1.0, "arch", slab=False), GIANT)
    assert s.component_of([3, 0, 3]) == s.component_of([9, 0, 3]) == 0


@pytest.mark.parametrize("flip", [False, True])
def test_floor_under_a_standing_box_is_not_walkable(flip):
    """A tall box standing on a closed floor slab (its foot coincides with the floor): the
    floor under it is inside the box, its top is walkable, the floor around it too."""
    env = env_of(box((0, -0.1, 0), (1, 0, 1)), box((0.3, 0, 0.3), (0.7, 0.3, 0.7)), flip=flip)
    s = build(env, replace(BASE, radius=0.05, height=0.1, cell_size=0.01))
    assert not s.is_walkable([[0.5, 0.0, 0.5]])[0]
    assert s.is_walkable([[0.5, 0.3, 0.5]])[0]
    assert s.is_walkable([[0.1, 0.0, 0.5]])[0]


@pytest.mark.parametrize("flip", [False, True])
def test_stacked_boxes(flip):
    """A smaller box resting on a larger one (coincident faces, no shared vertex), on an open
    floor: the lower box's top beside the upper box is walkable, under it is not, and the floor
    around both is walkable; nothing inside either box is."""
    env = env_of(floor(0, 1, 0, 1), box((0.2, 0, 0.2), (0.8, 0.2, 0.8)),
                 box((0.35, 0.2, 0.35), (0.65, 0.45, 0.65)), flip=flip)
    s = build(env, replace(BASE, radius=0.03, height=0.1, cell_size=0.01))
    assert s.is_walkable([[0.5, 0.45, 0.5], [0.27, 0.2, 0.5], [0.1, 0.0, 0.5]]).all()
    p = s.positions
    under = (np.abs(p[:, 0] - 0.5) < 0.14) & (np.abs(p[:, 2] - 0.5) < 0.14) & (p[:, 1] < 0.44)
    assert not under.any()


def test_mixed_winding_solid_still_counts_hits():
    """A closed box whose faces disagree about their winding is told apart by counting hits:
    the floor under a box hovering above it (with headroom for the agent) is walkable, the
    box's inside is not."""
    b = box((0.3, 0.2, 0.3), (0.7, 0.4, 0.7))
    f = np.asarray(b.faces).copy()
    f[::3] = f[::3, ::-1]
    b = trimesh.Trimesh(b.vertices, f, process=False)
    s = build(env_of(floor(), b), replace(BASE, radius=0.03, height=0.1, cell_size=0.01))
    assert s.is_walkable([[0.5, 0.0, 0.5], [0.5, 0.4, 0.5]]).all()
    p = s.positions
    assert not ((p[:, 1] > 0.01) & (p[:, 1] < 0.39)).any()
