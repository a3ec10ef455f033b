"""Randomness per subsystem (baker/streams.py): adding a prey changes none of the wander
targets the brain chooses before it first sees a prey, and the streams are addressed by name,
not by the order they are made in."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from baker.config import BakeConfig
from baker.pipeline import bake
from baker.streams import SUBSYSTEMS, Streams

pytestmark = pytest.mark.slow


def test_streams_are_independent_and_repeatable():
    a, b = Streams(7), Streams(7)
    assert np.array_equal(a.get("brain").random(5), b.get("brain").random(5))
    first = {name: Streams(7).get(name).random(3) for name in SUBSYSTEMS}
    # asking for the streams in another order gives the same numbers
    for name in reversed(list(SUBSYSTEMS)):
        assert np.array_equal(Streams(7).get(name).random(3), first[name])
    draws = ([Streams(7).get("prey", i).random(3) for i in range(3)]
             + [d for name, d in first.items() if name != "prey"])
    assert len({d.tobytes() for d in draws}) == len(draws)        # no two streams alike
    assert not np.array_equal(Streams(7, creature=1).get("brain").random(3), first["brain"])
    assert not np.array_equal(Streams(8).get("brain").random(3), first["brain"])


def wander_targets(report: dict, before: float) -> list[tuple]:
    return [tuple(e["details"]["target"]) for e in report["timeline"]
            if e["state"] == "wander" and e["start"] < before and "target" in e["details"]]


def first_sighting(report: dict) -> float:
    """When the brain first reacts to a prey (the start of its first hunt)."""
    return min((e["start"] for e in report["timeline"] if e["state"] == "hunt"), default=np.inf)


@pytest.mark.parametrize("seed", [3, 11, 23])
def test_adding_a_prey_keeps_the_wander_targets_chosen_before_it_is_seen(
        tmp_path, nav_cache_dir, spine_rig_config, seed):
    base = BakeConfig(seconds=40.0, seed=seed, prey=0, rig=spine_rig_config, formats=("glb",),
                      nav_cache_dir=nav_cache_dir, out=tmp_path / "none", tolerance=0.0)
    alone = bake(base).report
    with_prey = bake(replace(base, prey=1, out=tmp_path / "one")).report
    seen = first_sighting(with_prey)
    before = wander_targets(with_prey, seen)
    assert len(before) >= 1, "the prey was seen too early for the test to say anything"
    assert before == wander_targets(alone, seen)
    # and the start is the same
    assert alone["timeline"][0]["details"] == with_prey["timeline"][0]["details"] or \
        alone["timeline"][0]["state"] != "wander"
