"""Which side of an open surface is walked on (navmesh.build._open_facing, _solids): the side
its normal points to, as Recast, Unity and Godot build navigation, unless the whole file is
wound the other way round. A level modelled as the inside of a shell (Recast's dungeon, a
Quake-style arena from Godot's demos) has its floors facing up and its ceilings and its bottom
facing down: read two-sided, the backs of the ceilings (the roofs outside the level) and of the
bottom (the void under it) were walkable too, and the start, on the largest region, fell there
(the arena: a bake under the level's bottom; the dungeon: about half its walkable samples on
its roofs)."""

from __future__ import annotations

import numpy as np

from baker.navmesh import build
from baker.navmesh.build import _open_facing, _solid_components
from test_navmesh_scenes import AGENT, env_of, floor


def _down(m):
    """The mesh with its winding reversed (its normals facing the other way)."""
    out = m.copy()
    out.faces = out.faces[:, ::-1]
    return out


def _heights(s) -> np.ndarray:
    return np.unique(np.round(np.asarray(s.data.positions)[:, 1], 3))


def shell(flip=False):
    """A room's floor (y = 0, facing up) under its ceiling (y = 0.3, facing down), over the
    level's bottom (y = -0.3, facing down), all open sheets."""
    return env_of(floor(0.0, 1.0, 0.0, 1.0), _down(floor(0.0, 1.0, 0.0, 1.0, y=0.3)),
                  _down(floor(-0.5, 1.5, -0.5, 1.5, y=-0.3)), flip=flip)


def test_the_roof_and_the_void_under_a_shell_level_are_not_walked():
    s = build(shell(), AGENT)
    assert _heights(s).tolist() == [0.0]
    assert s.is_walkable([[0.5, 0.0, 0.5]])[0]
    assert not s.is_walkable([[0.5, 0.3, 0.5]])[0]
    assert not s.is_walkable([[1.3, -0.3, 1.3]])[0]


def test_a_file_wound_the_other_way_round_is_walked_on_its_top():
    env = env_of(floor(0.0, 1.0, 0.0, 1.0), flip=True)
    comp, closed, _ = _solid_components(env.mesh)
    assert _open_facing(env.mesh, closed[comp]) == -1.0
    s = build(env, AGENT)
    assert s.is_walkable([[0.5, 0.0, 0.5]])[0]


def test_a_double_sided_floor_is_walked_whichever_face_a_ray_meets_first():
    """The same floor modelled twice, once each way (both orders), in a level whose other
    open faces face up: walkable as the floor alone is."""
    room = floor(2.0, 3.0, 0.0, 1.0)
    for pair in ((floor(), _down(floor())), (_down(floor()), floor())):
        s = build(env_of(room, *pair), AGENT)
        assert s.is_walkable([[0.5, 0.0, 0.5]])[0]
        assert s.is_walkable([[2.5, 0.0, 0.5]])[0]


def test_a_face_down_floor_in_an_upright_level_is_not_walked():
    """The rule engines follow: within a file wound one way, a face's back is not a floor."""
    s = build(env_of(floor(2.0, 3.0, 0.0, 1.0), floor(4.0, 5.0, 0.0, 1.0),
                     _down(floor(0.0, 1.0, 0.0, 1.0))), AGENT)
    assert s.is_walkable([[2.5, 0.0, 0.5]])[0]
    assert not s.is_walkable([[0.5, 0.0, 0.5]])[0]


def test_a_floor_wound_at_random_is_walked_from_either_side():
    """Half its triangles wound each way (a file whose winding says nothing: its faces
    disagree along half their shared edges, a shell level's along 0.2 %): read two-sided, as
    before, not cut to a sieve."""
    rng = np.random.default_rng(4)
    m = floor()
    m = m.subdivide().subdivide().subdivide()
    f = np.asarray(m.faces).copy()
    flip = rng.random(len(f)) < 0.5
    f[flip] = f[flip][:, ::-1]
    m.faces = f
    s = build(env_of(m), AGENT)
    assert all(s.is_walkable([[x, 0.0, z]])[0] for x in (0.3, 0.5, 0.7) for z in (0.3, 0.5, 0.7))
