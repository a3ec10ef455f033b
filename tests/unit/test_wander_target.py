"""The brain keeps a wander target it has not reached when the d10 says wander again
(rig `wander.keep_target`), so a walk to another room or up a staircase is not cut short every
decision interval; it draws a new one once the target is reached, or once it has been kept
that long. A target on another floor is a journey (`wander.journey_rise`, `journey_time`): no
d10 is rolled until it arrives. Driven step by step with Senses on a flat 2 x 2 m floor and on
a floor with a deck stacked over it and a bank beside it, shade and prey off."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh.convex

from baker.behaviour import perception
from baker.behaviour.brain import Brain, Senses
from baker.behaviour.sun import SunPath
from baker.config import DEFAULT_RIG, load_rig_config
from baker.navmesh import build
from test_navmesh_scenes import box, env_of, floor

RIG = load_rig_config(DEFAULT_RIG)


@pytest.fixture(scope="module")
def scene():
    env = env_of(floor(-1.0, 1.0, -1.0, 1.0))
    return env, build(env, RIG.navigation)


def brain(scene, keep: float) -> Brain:
    env, nav = scene
    rig = replace(RIG, wander=replace(RIG.wander, keep_target=keep))
    sun = SunPath(np.array([[0.0, 1.0, 0.0]]), 60.0)
    return Brain(rig, nav, env.rays, sun, np.random.default_rng(3), [], mode="wander",
                 cobra_mode="never")


def targets(b: Brain, seconds: float, arrived=lambda t: False) -> list[tuple[float, tuple]]:
    """(time, target) of every new target over `seconds` of 240 Hz steps, the head still."""
    out = []
    for k in range(int(seconds * 240)):
        t = k / 240
        intent = b.step(Senses(t, np.zeros(3), np.array([0.0, 0.0, 1.0]), arrived(t)))
        if intent.new_target:
            out.append((t, tuple(np.round(intent.target, 6))))
    return out


def test_a_target_not_reached_is_kept_until_keep_target(scene):
    interval = RIG.behaviour.decision_interval
    keep = 3 * interval
    got = targets(brain(scene, keep), 2 * keep + 1.0)
    times = [t for t, _ in got]
    # rolls every interval, a new target only every `keep` seconds
    assert times == pytest.approx([0.0, keep, 2 * keep], abs=1e-6)
    assert len({p for _, p in got}) == 3


def test_a_reached_target_is_replaced_at_the_next_roll(scene):
    interval = RIG.behaviour.decision_interval
    got = targets(brain(scene, 1000.0), 3 * interval + 1.0, arrived=lambda t: t > 1.0)
    assert [t for t, _ in got] == pytest.approx([0.0, interval, 2 * interval, 3 * interval],
                                               abs=1e-6)


def test_keep_target_zero_is_seeds_new_target_at_every_roll(scene):
    interval = RIG.behaviour.decision_interval
    got = targets(brain(scene, 0.0), 2 * interval + 1.0)
    assert [t for t, _ in got] == pytest.approx([0.0, interval, 2 * interval], abs=1e-6)


# --------------------------------------------------------------------------- journeys
# A ground floor 6.5 x 4 m at y = 0; a deck (top 0.4 m, 1.6 BL) stacked over its middle with
# 0.35 m of headroom, reached by a solid ramp; a solid bank as high as the deck in the west,
# reached by its slope (a hillside: one layer everywhere).
DECK_Y = 0.4


def wedge(x_foot: float, x_top: float, x_end: float) -> trimesh.Trimesh:
    """A solid slope from the floor at x_foot up to DECK_Y at x_top, then flat to x_end,
    z in [-1, 1]."""
    xs = [(x_foot, 0.0), (x_top, DECK_Y), (x_end, DECK_Y), (x_end, 0.0), (x_top, 0.0)]
    return trimesh.convex.convex_hull(np.array([(x, y, z) for x, y in xs for z in (-1.0, 1.0)]))


@pytest.fixture(scope="module")
def storeys():
    env = env_of(floor(-3.0, 3.5, -2.0, 2.0), box((0.5, 0.35, -1.0), (2.0, DECK_Y, 1.0)),
                 wedge(2.8, 2.0, 2.0), wedge(-0.2, -1.0, -2.5))
    return env, build(env, RIG.navigation)


ON_DECK = np.array([1.25, DECK_Y, 0.0])
UNDER_DECK = np.array([1.25, 0.0, 0.0])
OPEN_GROUND = np.array([0.0, 0.0, 1.6])
ON_BANK = np.array([-1.75, DECK_Y, 0.0])


def test_the_scene_has_the_layers_the_journey_tests_assume(storeys):
    _, nav = storeys
    pts = np.array([ON_DECK, UNDER_DECK, OPEN_GROUND, ON_BANK])
    assert nav.is_walkable(pts).all()
    # the ground under the bank is inside it: one layer there
    assert np.isnan(nav.surface_height(np.array([[-1.75, 0.0, 0.0]]), tol=0.1)[0])


@pytest.mark.parametrize("head, target, expected", [
    (UNDER_DECK, ON_DECK, True),      # up to the floor over the head
    (OPEN_GROUND, ON_DECK, True),     # up to a floor stacked over the ground floor
    (ON_DECK, OPEN_GROUND, True),     # down from it, to ground in the open
    (ON_DECK, UNDER_DECK, True),
    (OPEN_GROUND, ON_BANK, False),    # a hillside: nothing under the bank's top
    (ON_BANK, OPEN_GROUND, False),
    (UNDER_DECK, ON_BANK, False),     # a bank as high as the deck the head is under
    (OPEN_GROUND, UNDER_DECK, False),  # the same floor
])
def test_on_another_floor_tells_stacked_floors_from_a_hillside(storeys, head, target, expected):
    _, nav = storeys
    assert perception.on_another_floor(nav, head, target, RIG.wander.journey_rise) is expected
    assert perception.on_another_floor(nav, head, target, 0.45) is False   # rise above 0.4 m


def test_a_tiny_journey_rise_samples_the_path_no_finer_than_the_cells(storeys, monkeypatch):
    """A rig may set journey_rise as small as it likes: the path is sampled every cell at the
    finest (every 1e-9 m, a few metres of path were 3 GB of points)."""
    _, nav = storeys
    asked = []
    real = type(nav).resample_path

    def spy(self, points, spacing=None):
        asked.append(spacing)
        return real(self, points, spacing)

    monkeypatch.setattr(type(nav), "resample_path", spy)
    assert perception.on_another_floor(nav, UNDER_DECK, ON_DECK, 1e-9) is True
    assert perception.on_another_floor(nav, OPEN_GROUND, UNDER_DECK, 1e-9) is False
    assert asked == [nav.cell_size]          # (the second: the same height, no path asked)


class Draws:
    """The scene's walkable surface, whose wander draws are the given points in turn."""

    def __init__(self, nav, points):
        self._nav, self._points = nav, list(points)

    def random_point_near(self, p, radius, rng):
        return self._points.pop(0).copy()

    def __getattr__(self, name):
        return getattr(self._nav, name)


def walk(storeys, points, seconds, arrived_at=np.inf, journey_time=None):
    """The timeline of a wander-only brain whose draws are `points`, the head still on the
    open ground (arrived from `arrived_at` on)."""
    env, nav = storeys
    w = RIG.wander if journey_time is None else replace(RIG.wander, journey_time=journey_time)
    b = Brain(replace(RIG, wander=w), Draws(nav, points), env.rays,
              SunPath(np.array([[0.0, 1.0, 0.0]]), 60.0), np.random.default_rng(3), [],
              mode="wander", cobra_mode="never")
    for k in range(int(seconds * 240)):
        t = k / 240
        b.step(Senses(t, OPEN_GROUND.copy(), np.array([0.0, 0.0, 1.0]), t >= arrived_at))
    return b.finish(seconds)


def test_a_journey_to_another_floor_goes_on_through_the_rolls(storeys):
    interval, journey = RIG.behaviour.decision_interval, RIG.wander.journey_time
    assert RIG.wander.keep_target == 0.0 and journey > 2 * interval
    ev = walk(storeys, [ON_DECK, UNDER_DECK, OPEN_GROUND, ON_BANK] * 10, journey + interval + 1.0)
    starts = [e["start"] for e in ev]
    # the deck is drawn first: no roll until the journey has lasted journey_time, then a new
    # target at every roll (the same floor, not journeys)
    assert ev[0]["details"] == {"roll": ev[0]["details"]["roll"], "target": list(ON_DECK),
                                "journey": True}
    assert starts[:2] == pytest.approx([0.0, journey], abs=1e-6)
    assert all("journey" not in e["details"] for e in ev[1:])
    assert starts[2] == pytest.approx(journey + interval, abs=1e-6)


def test_a_journey_ends_when_the_head_arrives(storeys):
    interval = RIG.behaviour.decision_interval
    ev = walk(storeys, [ON_DECK, OPEN_GROUND, ON_BANK, UNDER_DECK], 3 * interval + 1.0,
              arrived_at=interval + 1.0)
    assert [e["start"] for e in ev] == pytest.approx([0.0, 2 * interval, 3 * interval],
                                                     abs=1e-6)


def test_journey_time_zero_is_seeds_new_target_at_every_roll(storeys):
    interval = RIG.behaviour.decision_interval
    ev = walk(storeys, [ON_DECK, ON_DECK, ON_DECK], 2 * interval + 1.0, journey_time=0.0)
    assert [e["start"] for e in ev] == pytest.approx([0.0, interval, 2 * interval], abs=1e-6)
    assert all("journey" not in e["details"] for e in ev)
