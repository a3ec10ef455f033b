"""The brain keeps a wander target it has not reached when the d10 says wander again
(rig `wander.keep_target`), so a walk to another room or up a staircase is not cut short every
decision interval; it draws a new one once the target is reached, or once it has been kept
that long. Driven step by step with Senses on a flat 2 x 2 m floor, shade and prey off."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from baker.behaviour.brain import Brain, Senses
from baker.behaviour.sun import SunPath
from baker.config import DEFAULT_RIG, load_rig_config
from baker.navmesh import build
from test_navmesh_scenes import env_of, floor

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
