"""A crowd's perceptions measured together (behaviour.brain.sense_together: one surface query
and one ray batch per kind for all the brains perceiving in a step) are each brain's own, bit
for bit, and a brain's step uses the one kept for it (run.crowd measures them ahead of the
step). Brains on a floor with a low box (an obstacle to rear at) and a roof casting shade."""

from __future__ import annotations

import numpy as np
import pytest

from baker.behaviour.brain import Brain, Senses, sense_together
from baker.behaviour.sun import SunPath
from baker.config import DEFAULT_RIG, load_rig_config
from baker.navmesh import build
from test_navmesh_scenes import box, env_of, floor

RIG = load_rig_config(DEFAULT_RIG)


@pytest.fixture(scope="module")
def scene():
    c = RIG.cobra
    low = 0.5 * (RIG.navigation.step_height + c.height)      # taller than a step, under the cobra
    env = env_of(floor(-2.0, 2.0, -2.0, 2.0), box((0.3, 0.0, -0.5), (0.5, low, 0.5)),
                 box((-1.5, 0.6, -1.5), (-0.5, 0.62, -0.5)))   # a roof: shade under it
    return env, build(env, RIG.navigation)


def brains_and_senses(scene, n: int = 6):
    env, nav = scene
    sun = SunPath(np.array([[0.3, 1.0, 0.2]]) / np.linalg.norm([0.3, 1.0, 0.2]), 60.0)
    rng = np.random.default_rng(5)
    heads = np.column_stack([rng.uniform(-1.4, 0.25, n), np.zeros(n), rng.uniform(-1.4, 0.4, n)])
    # beside the box, close: 0 and 3 face it, 1 and 4 turn their backs on it
    near = 0.5 * RIG.cobra.obstacle_probe
    heads[0], heads[1] = [0.3 - near, 0.0, 0.0], [0.3 - near, 0.0, 0.2]
    heads[3], heads[4] = [0.5 + near, 0.0, -0.2], [0.5 + near, 0.0, 0.3]
    facing = {0: [1.0, 0.0, 0.0], 1: [-1.0, 0.0, 0.0], 3: [-1.0, 0.0, 0.0], 4: [1.0, 0.0, 0.0]}
    brains, senses = [], []
    for i, h in enumerate(heads):
        b = Brain(RIG, nav, env.rays, sun, np.random.default_rng(i), [], mode="auto",
                  cobra_mode="never" if i % 3 == 2 else "auto")
        b.state = ("wander", "seek_shade", "rest_in_shade")[i % 3]
        brains.append(b)
        heading = np.array(facing.get(i, [np.cos(i), 0.0, np.sin(i)]))
        senses.append(Senses(0.25 * i, h, heading, False))
    return brains, senses


def test_the_senses_measured_together_are_each_brains_own(scene):
    brains, senses = brains_and_senses(scene)
    together = sense_together(brains, senses)
    alone = [sense_together([b], [s])[0] for b, s in zip(brains, senses)]
    for a, b in zip(together, alone):
        assert a[4] == b[4]                                         # the obstacle (or None)
        for x, y in zip(a[:4], b[:4]):
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes()
    # the scene gives them something to tell apart: an obstacle, shade and open ground
    assert [t[4] for t in together][:5] == [True, False, None, True, False]
    shade = np.array([t[3] for t in together])
    assert shade.any() and not shade.all()


def test_a_brain_uses_the_senses_kept_for_it_and_only_for_those_senses(scene, monkeypatch):
    brains, senses = brains_and_senses(scene)
    kept = sense_together(brains, senses)
    b, s = brains[1], senses[1]
    monkeypatch.setattr(b.nav, "surface_height", lambda *a, **k: pytest.fail("measured again"))
    assert b._sense(s) is kept[1] and b._sensed is None
    monkeypatch.undo()
    sense_together(brains, senses)
    moved = Senses(s.t, s.head + [1e-9, 0.0, 0.0], s.heading, s.arrived)
    again = brains[1]._sense(moved)                                 # other senses: measured
    assert again is not kept[1] and again[1][0] != kept[1][1][0]
