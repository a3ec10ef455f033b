"""Thin upright parts (a seedling's stem, a post) narrower than a cell: the link rays between
column centres can pass on either side of one, and the creature then walked right through it.
The samples around such a part are kept a radius clear of it, like those beside a wall."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
import trimesh

from baker.config import DEFAULT_RIG, load_rig_config
from baker.navmesh import build
from test_navmesh_scenes import env_of, floor

AGENT = load_rig_config(DEFAULT_RIG).navigation
CELL = AGENT.cell_size


def post_scene(cx: float, cz: float, r: float = 0.006, h: float = 0.3):
    """A 0.6 m floor and an 8-sided post of radius r (a stem), standing from below the floor."""
    post = trimesh.creation.cylinder(radius=r, height=h, sections=8)   # along z
    post.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))
    post.apply_translation((cx, 0.5 * h - 0.02, cz))
    return env_of(floor(0.0, 0.6, 0.0, 0.6), post)


# the post at every quarter cell across one cell: some of these put it between every grid line
OFFSETS = [(a, b) for a in (0.0, 0.25, 0.5, 0.75) for b in (0.0, 0.25, 0.5, 0.75)]


@pytest.mark.parametrize("du, dv", OFFSETS)
def test_no_walkable_sample_within_a_radius_of_a_thin_post(du, dv):
    cx, cz = 0.3 + du * CELL, 0.3 + dv * CELL
    nav = build(post_scene(cx, cz), AGENT)
    p = nav.data.positions
    d = np.hypot(p[:, 0] - cx, p[:, 2] - cz) - 0.006
    assert d.min() >= AGENT.radius - 0.75 * CELL, (d.min(), AGENT.radius)


def test_a_thick_part_is_left_to_the_link_rays():
    """The sides of a part wider than THIN_POST cells (a 10 cm block) are left to the link
    rays, which always meet them; the stem's are thin."""
    b = importlib.import_module("baker.navmesh.build")
    block = trimesh.creation.box((0.1, 0.2, 0.1))
    block.apply_translation((0.3, 0.08, 0.3))
    env = env_of(floor(0.0, 0.6, 0.0, 0.6), block)
    lo, _ = b._thin_parts(b._Caster(env), CELL, AGENT.max_slope)
    assert len(lo) == 0
    lo, _ = b._thin_parts(b._Caster(post_scene(0.3, 0.3)), CELL, AGENT.max_slope)
    assert len(lo) == 16                  # the post's sides (its caps are flat)
