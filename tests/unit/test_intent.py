"""The Intent record (behaviour.intent): what a decision maker hands the run stage each step."""

import dataclasses

import numpy as np
import pytest

from baker.behaviour.brain import Senses
from baker.behaviour.intent import Intent
from baker.behaviour.script import Drive, ScriptedIntent


def _senses(t):
    return Senses(t, np.zeros(3), np.array([0.0, 0.0, 1.0]), False)


def test_a_scripted_timeline_gives_intents_with_its_drives():
    route = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    it = ScriptedIntent([Drive(0.0, "walk", route=route, speed_scale=0.5),
                         Drive(1.0, "cobra_rear", halt=True, cobra=1.0, warning=1.0)])
    first = it.step(_senses(0.0))
    assert isinstance(first, Intent)
    assert first.new_target and not first.halt and first.speed_scale == 0.5
    np.testing.assert_array_equal(first.target, route[-1])
    np.testing.assert_array_equal(first.route, route)
    walking = it.step(_senses(0.5))
    assert not walking.new_target and walking.speed_scale == 0.5
    assert it.step(_senses(0.6)) is walking      # unchanged drives: the same record, no allocation
    rear = it.step(_senses(1.0))
    assert rear.halt and rear.target is None and rear.cobra == 1.0 and rear.warning == 1.0
    assert not it.step(_senses(1.1)).halt        # a halt is one step's event


def test_an_intent_is_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        Intent().speed_scale = 2.0
