"""The head's surface test measures a step on a ramp net of the ramp's rise, as the navigation
links it (contain.SurfaceTest's `slope`, run.follow.Follower._slope). On a Quake-style arena
(Godot's zdm2.glb, the 2 m rig) a 0.18 m step on top of a 27 deg ramp is linked (its riser net
of the ramp's rise over a cell is under the 0.2 m step height), the path ran over it, but the
head's test, which took a point only where a layer lay within half the agent height of the
head's own height, measured it raw (0.30 m): the head could not follow, the agent waited for
it, and the creature turned round and round on the ramp for the rest of the bake, coiled so
tightly that its legs broke every limit."""

from __future__ import annotations

import math

import numpy as np

from baker.locomotion.contain import FLAT, SurfaceTest, plain_test
from baker.navmesh import build
from test_navmesh_scenes import AGENT, env_of, quad

GRADE = 0.5                         # the ramp's rise a metre (26.6 deg)
STEP = 0.8 * AGENT.step_height      # a step on its top, under the step height
TOL = 0.5 * AGENT.height            # the follower's layer reach


def ramp_and_step():
    """A ramp rising along +z from y = 0 at z = 0 to z = 0.4, then, up a step, a flat top."""
    top = GRADE * 0.4
    return env_of(quad((0, 0, 0), (0, top, 0.4), (1, top, 0.4), (1, 0, 0)),
                  quad((0, top, 0.4), (0, top + STEP, 0.4), (1, top + STEP, 0.4), (1, top, 0.4)),
                  quad((0, top + STEP, 0.4), (0, top + STEP, 0.8), (1, top + STEP, 0.8),
                       (1, top + STEP, 0.4)))


def test_a_step_on_a_ramp_is_a_step_net_of_the_ramp():
    nav = build(ramp_and_step(), AGENT)
    head = (0.5, 0.3)                                  # on the ramp, 0.1 m below its top
    y = GRADE * head[1]
    assert nav.find_path([0.5, y, head[1]], [0.5, 0.2 + STEP, 0.6]).complete
    slope = (head[0], head[1], 0.0, GRADE)
    ahead = [(0.5, z) for z in (0.36, 0.42, 0.45, 0.5)]   # up the ramp, over the step, on
    for make in (SurfaceTest, plain_test):
        raw = make(nav, y, TOL)
        netted = make(nav, y, TOL, slope=slope)
        assert not all(raw(x, z) for x, z in ahead)    # the old test: blocked
        assert all(netted(x, z) for x, z in ahead)


def test_the_compiled_test_and_the_python_one_agree_with_a_slope():
    nav = build(ramp_and_step(), AGENT)
    rng = np.random.default_rng(3)
    for _ in range(200):
        hx, hz = rng.uniform(0.1, 0.9), rng.uniform(0.05, 0.75)
        y = nav.layer_height(hx, 1.0, hz, 2.0)
        g = rng.uniform(-1.0, 1.0, 2) * math.tan(AGENT.max_slope) * 0.7
        slope = (hx, hz, float(g[0]), float(g[1])) if rng.random() < 0.8 else FLAT
        a, b = SurfaceTest(nav, y, TOL, slope=slope), plain_test(nav, y, TOL, slope=slope)
        for x, z in rng.uniform(0.0, 1.0, (10, 2)):
            assert a(x, z) == b(x, z)


def test_the_head_walks_up_a_ramp_and_onto_its_step_on_the_layer():
    """A Follower (the default rig: step 0.1 BL, half the agent height) sent from the foot of
    a ramp onto a top a step above its upper end, linked: the head gets onto the top, its
    height the top's (it used to stop at the step, or walk on at the ramp's height inside the
    top)."""
    from baker.config import DEFAULT_RIG, SIM_RATE_HZ, load_rig_config
    from baker.run.follow import Follower

    rig = load_rig_config(DEFAULT_RIG)
    nv = rig.navigation
    grade, run_z = 0.5, 0.4
    # a step a little over the step height: linked, its riser net of the ramp's rise over a
    # cell under it (as on the arena's ridge)
    top = grade * run_z + nv.step_height + 0.4 * grade * nv.cell_size
    env = env_of(quad((0, 0, 0), (0, grade * run_z, run_z), (1, grade * run_z, run_z), (1, 0, 0)),
                 quad((0, grade * run_z, run_z), (0, top, run_z), (1, top, run_z),
                      (1, grade * run_z, run_z)),
                 quad((0, top, run_z), (0, top, 1.0), (1, top, 1.0), (1, top, run_z)))
    nav = build(env, nv)
    goal = nav.nearest([0.5, top, 0.8])
    assert abs(goal[1] - top) < 1e-3
    assert nav.find_path(nav.nearest([0.5, 0.0, 0.05]), goal).complete
    f = Follower(nav, env.rays, nav.nearest([0.5, 0.0, 0.05]), np.array([0.0, 0.0, 1.0]), rig)
    f.go(goal)
    dt = 1.0 / SIM_RATE_HZ
    for _ in range(int(15.0 / dt)):
        f.step(dt)
        ground = nav.layer_height(f.head.base[0], f.height, f.head.base[2], 1e-3)
        assert ground == ground          # on a layer of the surface, never inside the top
    assert f.head.base[2] > 0.6 and abs(f.height - top) < 1e-3
