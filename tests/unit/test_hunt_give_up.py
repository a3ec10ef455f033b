"""A hunt gives up on a prey that stays out of range (beyond 1.2 detection ranges) or out of
reach (no walkable point of the hunter's component within striking distance of it) for
GIVE_UP_TIME, unless the hunter is gaining on it: a prey whose burst has tired is chased on
while the gap shrinks (within GAIN_RANGE detection ranges); a prey out of reach is not hunted. Driven step by step with Senses on a
flat 2 x 2 m floor, the prey a stand-in that the test moves."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from baker.behaviour.brain import GAIN_RANGE, GIVE_UP_TIME, Brain, Senses
from baker.behaviour.prey import FREE
from baker.behaviour.sun import SunPath
from baker.config import DEFAULT_RIG, load_rig_config
from baker.navmesh import build
from test_navmesh_scenes import env_of, floor

RIG = load_rig_config(DEFAULT_RIG)
DET = RIG.behaviour.detection_range
HZ = 240


@pytest.fixture(scope="module")
def scene():
    env = env_of(floor(-3.0, 3.0, -3.0, 3.0))
    return env, build(env, RIG.navigation)


def chase(scene, gap: float, closing: float, seconds: float) -> list[dict]:
    """The brain's events: a hunt starts with the prey just inside the detection range; the
    prey then jumps to `gap` m away and keeps still while the head closes at `closing` m/s."""
    env, nav = scene
    prey = SimpleNamespace(name="prey_01", mode=FREE, position=np.array([0.0, 0.0, 0.0]))
    b = Brain(RIG, nav, env.rays, SunPath(np.array([[0.0, 1.0, 0.0]]), 60.0),
              np.random.default_rng(1), [prey], mode="hunt", cobra_mode="never")
    head = np.array([-0.95 * DET, 0.0, 0.0])
    b.step(Senses(0.0, head.copy(), np.array([1.0, 0.0, 0.0]), False))
    assert b.state == "hunt"
    prey.position = head + [gap, 0.0, 0.0]
    for k in range(1, int(seconds * HZ)):
        head[0] += closing / HZ
        b.step(Senses(k / HZ, head.copy(), np.array([1.0, 0.0, 0.0]), False))
    return b.finish(seconds)


def test_a_prey_out_of_range_that_the_hunter_does_not_gain_on_escapes(scene):
    ev = chase(scene, 1.3 * DET, 0.0, GIVE_UP_TIME + 1.0)
    hunt = ev[0]
    assert hunt["state"] == "hunt" and hunt["details"]["outcome"] == "escaped"
    assert hunt["end"] == pytest.approx(GIVE_UP_TIME, abs=0.01)


def test_a_hunter_gaining_on_a_tired_prey_chases_on_until_it_is_in_range(scene):
    # closing at 0.04 detection ranges/s, it takes 2.5 s to get back within 1.2 of them,
    # longer than GIVE_UP_TIME
    ev = chase(scene, 1.3 * DET, 0.04 * DET, GIVE_UP_TIME + 2.0)
    assert [e["state"] for e in ev] == ["hunt"]
    assert "outcome" not in ev[0]["details"]


def test_gaining_does_not_hold_a_hunt_beyond_the_gain_range(scene):
    ev = chase(scene, (GAIN_RANGE + 0.2) * DET, 0.04 * DET, GIVE_UP_TIME + 1.0)
    assert ev[0]["details"]["outcome"] == "escaped"


@pytest.fixture(scope="module")
def island():
    """The hunter's floor (x < 0) and, 0.3 m beyond a gap, an island it cannot walk to."""
    env = env_of(floor(-3.0, 0.0, -3.0, 3.0), floor(0.3, 3.0, -3.0, 3.0))
    nav = build(env, RIG.navigation)
    assert nav.component_of([-1.0, 0.0, 0.0]) != nav.component_of([1.0, 0.0, 0.0])
    return env, nav


def _brain(scene, prey):
    env, nav = scene
    return Brain(RIG, nav, env.rays, SunPath(np.array([[0.0, 1.0, 0.0]]), 60.0),
                 np.random.default_rng(1), [prey], mode="hunt", cobra_mode="never")


def test_a_prey_seen_where_the_hunter_cannot_walk_is_not_hunted(island):
    """A prey within the detection range on the island: the hunter used to run to the
    nearest point it could reach and hunt on there as long as the prey stayed in range."""
    head = np.array([-0.1, 0.0, 0.0])
    prey = SimpleNamespace(name="prey_01", mode=FREE, position=head + [0.5 * DET, 0.0, 0.0])
    assert prey.position[0] > 0.3 + RIG.navigation.radius + RIG.behaviour.strike_range
    b = _brain(island, prey)
    for k in range(2 * HZ):
        b.step(Senses(k / HZ, head.copy(), np.array([1.0, 0.0, 0.0]), False))
        assert b.state != "hunt"
    # on the hunter's side of the gap, the same distance away, it is hunted
    prey.position = head - [0.5 * DET, 0.0, 0.0]
    for k in range(2 * HZ, 3 * HZ):
        b.step(Senses(k / HZ, head.copy(), np.array([1.0, 0.0, 0.0]), False))
    assert b.state == "hunt"


def test_a_hunt_whose_prey_goes_out_of_reach_gives_up(island):
    head = np.array([-0.5, 0.0, 0.0])
    prey = SimpleNamespace(name="prey_01", mode=FREE, position=head + [-0.5 * DET, 0.0, 0.0])
    b = _brain(island, prey)
    b.step(Senses(0.0, head.copy(), np.array([1.0, 0.0, 0.0]), False))
    assert b.state == "hunt"
    prey.position = np.array([0.3 + 0.5 * DET, 0.0, 0.0])      # onto the island, in range
    for k in range(1, int((GIVE_UP_TIME + 1.0) * HZ)):
        b.step(Senses(k / HZ, head.copy(), np.array([1.0, 0.0, 0.0]), False))
    hunt = b.finish(GIVE_UP_TIME + 1.0)[0]
    assert hunt["details"]["outcome"] == "out of reach"
    assert hunt["end"] == pytest.approx(GIVE_UP_TIME, abs=0.3)
