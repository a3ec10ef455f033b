"""After a meal the centipede is sated for behaviour.sated_time seconds: a prey in range starts
no hunt, and every d10 roll in that time sends it to a known shade spot (it digests in shade);
afterwards it hunts and rolls as before. Driven step by step with Senses on a flat floor, the
prey stand-ins that the test places."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from baker.behaviour.brain import Brain, Senses
from baker.behaviour.prey import FREE
from baker.behaviour.sun import SunPath
from baker.config import DEFAULT_RIG, load_rig_config
from baker.navmesh import build
from test_navmesh_scenes import env_of, floor

RIG = load_rig_config(DEFAULT_RIG)
HZ = 240
HEAD = np.array([0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def scene():
    env = env_of(floor(-3.0, 3.0, -3.0, 3.0))
    return env, build(env, RIG.navigation)


def meal_then(scene, rig, seconds: float, second_prey: bool = True):
    """A brain whose first prey sits at its head (hunt, strike, feed at once) and, with
    `second_prey`, a second one half a detection range away; two shade spots are known. Returns
    (events, when the feed ended)."""
    env, nav = scene
    beh = rig.behaviour
    first = SimpleNamespace(name="prey_01", mode=FREE, position=HEAD.copy())
    preys = [first]
    if second_prey:
        preys.append(SimpleNamespace(name="prey_02", mode=FREE,
                                     position=HEAD + [0.5 * beh.detection_range, 0.0, 0.0]))
    b = Brain(rig, nav, env.rays, SunPath(np.array([[0.0, 1.0, 0.0]]), 60.0),
              np.random.default_rng(3), preys[:1], mode="auto", cobra_mode="never")
    b.shade_spots = [np.array([1.0, 0.0, 1.0]), np.array([-1.0, 0.0, -1.0])]
    fed = None
    for k in range(int(seconds * HZ)):
        t = k / HZ
        if fed is None and b.state == "feed":
            fed = b.since + beh.feed_time     # the feed ends then
            b.preys = preys             # the second prey shows up while it eats
        b.step(Senses(t, HEAD.copy(), np.array([1.0, 0.0, 0.0]), False))
    return b.finish(seconds), fed


def test_a_sated_centipede_ignores_prey_in_range_until_sated_time_has_passed(scene):
    sated = RIG.behaviour.sated_time
    assert sated > 0.0
    ev, fed = meal_then(scene, RIG, RIG.behaviour.feed_time + sated + 3.0)
    hunts = [e for e in ev if e["state"] == "hunt"]
    assert hunts[0]["details"]["prey"] == "prey_01"
    second = [e for e in hunts if e["details"]["prey"] == "prey_02"]
    assert second, "the second prey is hunted once the centipede is hungry again"
    assert second[0]["start"] == pytest.approx(fed + sated, abs=0.2)


def test_every_roll_of_a_sated_centipede_goes_to_shade(scene):
    rig = replace(RIG, behaviour=replace(RIG.behaviour, decision_interval=1.0))
    sated = rig.behaviour.sated_time
    ev, fed = meal_then(scene, rig, rig.behaviour.feed_time + sated + 20.0, second_prey=False)
    rolls = [e for e in ev if "roll" in e["details"] and e["start"] > fed - 1e-6]
    during = [e for e in rolls if e["start"] < fed + sated]
    after = [e for e in rolls if e["start"] >= fed + sated]
    assert during[0]["start"] == pytest.approx(fed) and during[0]["state"] == "seek_shade"
    # whatever the roll (it is on its way, or resting): no wander while sated
    assert not [e for e in ev if e["state"] == "wander" and fed <= e["start"] < fed + sated]
    # hungry again, a roll above shade_roll_max sends it wandering
    assert any(e["state"] == "wander" for e in after)


def test_without_sated_time_it_hunts_the_next_prey_at_once(scene):
    rig = replace(RIG, behaviour=replace(RIG.behaviour, sated_time=0.0))
    ev, fed = meal_then(scene, rig, rig.behaviour.feed_time + 3.0)
    second = [e for e in ev if e["state"] == "hunt" and e["details"]["prey"] == "prey_02"]
    assert second and second[0]["start"] == pytest.approx(fed, abs=0.2)
