"""Where a creature starts (run/start.py), on a scene built in code: a start point at an edge,
where no heading has both a walkable body line behind and room ahead, is drawn again."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from baker.config import DEFAULT_RIG, load_rig_config
from baker.navmesh import build
from baker.run import start as start_mod
from baker.run.start import AHEAD, choose_start
from baker.streams import Streams
from test_navmesh_scenes import env_of, floor

RIG = load_rig_config(DEFAULT_RIG)
RIG = replace(RIG, navigation=replace(RIG.navigation, radius=0.08 * RIG.body.length))
L = RIG.body.length


@pytest.fixture(scope="module")
def patch():
    """A floor a little over two body lengths square: many points lie within a body length
    of an edge."""
    env = env_of(floor(0.0, 0.6, 0.0, 0.6))
    return env, build(env, RIG.navigation)


def clear(nav, start, heading) -> tuple[bool, bool]:
    """(the body line behind is walkable, the line AHEAD body lengths ahead is)"""
    behind = start - heading * np.linspace(0.0, L, 9)[:, None]
    ahead = start + heading * (AHEAD * L * np.arange(1, 5) / 4)[:, None]
    return bool(nav.is_walkable(behind).all()), bool(nav.is_walkable(ahead).all())


def starts(env, nav, seeds):
    return [choose_start(nav, env, L, Streams(s).get("start"), spread=np.inf, extent_frac=1.0)
            for s in seeds]


def test_a_start_at_an_edge_is_drawn_again(patch, monkeypatch):
    env, nav = patch
    seeds = range(40)
    for s, h in starts(env, nav, seeds):
        assert clear(nav, s, h) == (True, True)
    # with a single draw, some starts face an edge (or lie with the body off the surface)
    monkeypatch.setattr(start_mod, "START_DRAWS", 1)
    monkeypatch.setattr(start_mod, "WIDE_DRAWS", 0)
    once = [clear(nav, s, h) for s, h in starts(env, nav, seeds)]
    assert sum(c != (True, True) for c in once) >= 3


def test_the_first_draw_is_kept_when_it_has_room(patch):
    """A start with room is the one a single draw gives: bakes whose start has room are as
    they were."""
    env, nav = patch
    for seed in range(10):
        a = choose_start(nav, env, L, Streams(seed).get("start"), spread=np.inf, extent_frac=1.0)
        rng = Streams(seed).get("start")
        p = nav.random_point_near(start_mod.middle_anchor(nav, env), 0.6, rng)
        if clear(nav, p, a[1]) == (True, True):
            assert np.array_equal(a[0], p)


def test_a_given_point_and_heading_are_kept(patch):
    env, nav = patch
    s, h = choose_start(nav, env, L, Streams(0).get("start"), at=[0.02, 0.0, 0.3],
                        heading=[2.0, 0.0, 0.0])
    assert np.allclose(h, [1.0, 0.0, 0.0])
    assert np.linalg.norm((s - [0.02, 0.0, 0.3])[[0, 2]]) < 0.05


def test_a_cramped_middle_draws_out_to_the_whole_level(patch, monkeypatch):
    """Where no draw near the middle has a full body line (a tower's stair landing), draws go
    on out to the level's extent; the body had been laid through what the line crossed."""
    env, nav = patch
    anchor = start_mod.middle_anchor(nav, env)
    heading_of = start_mod._best_heading

    def cramped(nav_, p, length, rng, tail=0.0):
        score, h = heading_of(nav_, p, length, rng, tail)
        near = np.linalg.norm((p - anchor)[[0, 2]]) < 0.15
        return (min(score, start_mod._FULL - 10) if near else score), h

    monkeypatch.setattr(start_mod, "_best_heading", cramped)
    for seed in range(8):
        s, h = choose_start(nav, env, L, Streams(seed).get("start"), extent_frac=0.2)
        assert np.linalg.norm((s - anchor)[[0, 2]]) >= 0.15
        assert clear(nav, s, h) == (True, True)
    monkeypatch.setattr(start_mod, "WIDE_DRAWS", 0)      # as it was: the best partial line
    s, _ = choose_start(nav, env, L, Streams(0).get("start"), extent_frac=0.2)
    assert np.linalg.norm((s - anchor)[[0, 2]]) < 0.15


def test_prey_on_a_level_smaller_than_the_detection_range_start_away(patch):
    """Prey start 1.2 to 2 detection ranges away; where the level is smaller than that, at the
    farthest of their draws (they had started on the centipede's head)."""
    env, nav = patch
    rig = replace(RIG, behaviour=replace(RIG.behaviour, detection_range=2.0))
    start = start_mod.middle_anchor(nav, env)
    preys = start_mod.spawn_prey(3, start, nav, rig, Streams(5))
    for p in preys:
        assert np.linalg.norm((p.position - start)[[0, 2]]) > 0.15


def test_the_start_line_leaves_room_behind_the_tail_for_the_ultimate_legs():
    """A floor with a riser too tall to climb across one side: a start whose body line ends
    just short of the riser has its ultimate legs, trailing behind the tail, in the riser. The
    start line is sampled out to their reach (run.start.tail_reach), so the chosen heading
    leaves them room. Without it (a crowd on Recast's dungeon at 4x, seed 15300000): a tail
    started 2 cm from an 11 cm riser, its ultimate leg's base 0.5 mm inside it, and the leg
    jumped 32 degrees in a frame when the body walked it out."""
    from test_navmesh_scenes import box

    env = env_of(floor(-0.5, 0.5, -0.5, 0.5), box((-0.5, 0.0, -0.5), (0.5, 0.05, -0.2)))
    nav = build(env, RIG.navigation)
    tail = start_mod.tail_reach(RIG)
    assert tail > 0.1 * L
    where = [0.0, 0.0, -0.16 + 0.98 * L]        # a body length from the walkable edge
    reach = np.linspace(0.0, L + tail, 12)[:, None]
    old = []
    for seed in range(12):
        s, h = choose_start(nav, env, L, Streams(seed).get("start"), at=where, tail=tail)
        assert nav.is_walkable(s - h * reach).all()
        s, h = choose_start(nav, env, L, Streams(seed).get("start"), at=where)
        old.append(bool(nav.is_walkable(s - h * reach).all()))
    assert not all(old)        # the body line alone took headings with the legs in the riser
