"""The head's look-ahead walks its way by the navigation's links (contain._walk,
SurfaceTest.walk): every column from the head's base to the look-ahead's end on the layer reached
from the base's sample link by link, as the agent's paths are (navmesh.query.segment_visible). On a Quake-style arena
(Godot's zdm2.glb, the 2 m rig) the head got onto a ridge's level top and could not step down
onto the ramp beyond a 0.18 m step: the look-ahead measured every point against the head's
height, and a point past the edge lies below it by the step and by the ramp's fall as far as
the head looks. The creature turned on the top for the rest of the minute."""

from __future__ import annotations

import math

import numpy as np

from baker.locomotion.contain import FLAT, SurfaceTest, plain_test
from baker.locomotion.head import grid_array, way_points
from baker.navmesh import build
from test_navmesh_scenes import AGENT, env_of, quad

GRADE = 0.5                         # the ramp's fall a metre (26.6 deg)
TOL = 0.5 * AGENT.height            # the follower's layer reach
GRID = None


def top_step_ramp(step: float, run: float = 0.4, top_len: float = 0.4):
    """A flat top from z = 0 to top_len at height `run` x GRADE + step, then, down a step, a
    ramp falling along +z to y = 0 over `run`."""
    foot = GRADE * run
    top = foot + step
    z1, z2 = top_len, top_len + run
    return env_of(quad((0, top, 0), (0, top, z1), (1, top, z1), (1, top, 0)),
                  quad((0, top, z1), (0, foot, z1), (1, foot, z1), (1, top, z1)),
                  quad((0, foot, z1), (0, 0, z2), (1, 0, z2), (1, foot, z1))), top


def grid_of(nav):
    """The head's grid (Follower: the navigation's)."""
    return float(nav.origin[0]), float(nav.origin[1]), float(nav.cell_size)


def walks(test, nav, bx, bz, dx, dz, s, reach):
    """test.walk, the head's grid as SurfaceTest and plain_test take it."""
    g = grid_of(nav)
    return test.walk(bx, bz, dx, dz, s, reach, grid_array(g) if isinstance(test, SurfaceTest) else g)


def test_a_way_down_a_step_onto_a_ramp_is_walked_point_to_point():
    env, top = top_step_ramp(0.8 * AGENT.step_height)
    nav = build(env, AGENT)
    bx, bz = 0.5, 0.3                              # on the top, 0.1 m before its edge
    assert nav.find_path([bx, top, bz], [0.5, 0.05, 0.75]).complete
    # over the edge and 0.2 m down the ramp
    ts = [0.001, *way_points(bx, bz, 0.0, 1.0, 0.001, 0.3, grid_of(nav))]
    for make in (SurfaceTest, plain_test):
        test = make(nav, top, TOL)
        # each point measured against the head's height alone: blocked past the edge
        assert not all(test(bx, bz + t) for t in ts)
        assert walks(test, nav, bx, bz, 0.0, 1.0, 0.001, 0.3)


def test_a_drop_the_navigation_does_not_link_is_not_walked():
    env, top = top_step_ramp(1.5 * TOL)
    nav = build(env, AGENT)
    bx, bz = 0.5, 0.3
    assert not nav.find_path([bx, top, bz], [0.5, 0.05, 0.75]).complete
    for make in (SurfaceTest, plain_test):
        assert not walks(make(nav, top, TOL), nav, bx, bz, 0.0, 1.0, 0.001, 0.3)
        assert walks(make(nav, top, TOL), nav, bx, bz, 0.0, 1.0, 0.001, 0.03)   # on the top


def test_the_compiled_walk_and_the_python_one_agree():
    rng = np.random.default_rng(5)
    agree = walked = 0
    for step in (0.5 * TOL, 0.9 * TOL, 1.2 * TOL):
        env, _ = top_step_ramp(step)
        nav = build(env, AGENT)
        for _ in range(150):
            bx, bz = rng.uniform(0.05, 0.95), rng.uniform(0.05, 0.75)
            y = nav.layer_height(bx, 1.0, bz, 2.0)
            g = rng.uniform(-1.0, 1.0, 2) * math.tan(AGENT.max_slope) * 0.7
            slope = (bx, bz, float(g[0]), float(g[1])) if rng.random() < 0.5 else FLAT
            near = None
            if rng.random() < 0.3:                 # other bodies' points, nearest first
                pts = rng.uniform(0.0, 1.0, (6, 2))
                d = np.hypot(pts[:, 0] - bx, pts[:, 1] - bz)
                o = np.argsort(d)
                near = np.column_stack([d[o] - 1e-6, pts[o]])
            args = (nav, y, TOL, near, (bx, bz), 0.01 if near is not None else 0.0, slope)
            a, b = SurfaceTest(*args), plain_test(*args)
            a_ = rng.uniform(-math.pi, math.pi)
            dx, dz = math.cos(a_), math.sin(a_)
            reach = rng.uniform(0.0, 0.5)
            got = walks(a, nav, bx, bz, dx, dz, 0.002, reach)
            assert got == walks(b, nav, bx, bz, dx, dz, 0.002, reach)
            agree += 1
            walked += got
    assert agree == 450 and 0 < walked < agree      # both answers seen


def test_the_head_walks_down_a_step_onto_a_ramp():
    """A Follower (the default rig) sent from a flat top down a linked step onto the ramp
    beyond it walks down the ramp (it used to stop at the edge)."""
    from baker.config import DEFAULT_RIG, SIM_RATE_HZ, load_rig_config
    from baker.run.follow import Follower

    rig = load_rig_config(DEFAULT_RIG)
    nv = rig.navigation
    # a step a little over the step height: linked, its riser net of the ramp's fall over a
    # cell under it (as on the arena's ridge)
    env, top = top_step_ramp(nv.step_height + 0.4 * GRADE * nv.cell_size, run=0.4, top_len=0.6)
    nav = build(env, nv)
    start, goal = nav.nearest([0.5, top, 0.1]), nav.nearest([0.5, 0.0, 0.95])
    assert abs(start[1] - top) < 1e-3 and goal[1] < 0.05
    assert nav.find_path(start, goal).complete
    f = Follower(nav, env.rays, start, np.array([0.0, 0.0, 1.0]), rig)
    f.go(goal)
    dt = 1.0 / SIM_RATE_HZ
    for _ in range(int(15.0 / dt)):
        f.step(dt)
        ground = nav.layer_height(f.head.base[0], f.height, f.head.base[2], 1e-3)
        assert ground == ground          # on a layer of the surface
    # well down the ramp (the agent arrives within its stopping distance of the goal)
    assert f.head.base[2] > 0.75 and f.height < 0.5 * top


def test_the_walk_crosses_exactly_the_columns_the_way_crosses():
    """On a grid of linked columns with one column missing, a way is walked exactly when the
    straight segment from the base to the look-ahead's end misses that column's square (the
    DDA visits every column the segment crosses, corners included, and no other)."""
    from types import SimpleNamespace

    from test_head_compiled import links_of

    n, cell, hole = 12, 0.1, (5, 6)
    pos, starts = [], [0]
    for ix in range(n):
        for iz in range(n):
            if (ix, iz) != hole:
                pos.append(((ix + 0.5) * cell, 0.0, (iz + 0.5) * cell))
            starts.append(len(pos))
    nav = SimpleNamespace(origin=(0.0, 0.0), cell_size=cell, shape=(n, n),
                          col_start=np.array(starts, dtype=np.int64),
                          positions=np.array(pos, dtype=np.float32),
                          normals=np.tile(np.float32([0.0, 1.0, 0.0]), (len(pos), 1)),
                          _cache={})
    nav.links = links_of(nav, 0.05)
    test = SurfaceTest(nav, 0.0, 0.01)
    box = np.array([hole[0] * cell, hole[1] * cell, (hole[0] + 1) * cell, (hole[1] + 1) * cell])

    def meets(b, e, grow):
        """The segment b-e meets the hole's square grown by `grow` (Liang-Barsky)."""
        t0, t1 = 0.0, 1.0
        for k in range(2):
            d = e[k] - b[k]
            lo, hi = box[k] - grow, box[k + 2] + grow
            if abs(d) < 1e-15:
                if not lo <= b[k] <= hi:
                    return False
                continue
            a, c = sorted(((lo - b[k]) / d, (hi - b[k]) / d))
            t0, t1 = max(t0, a), min(t1, c)
        return t0 <= t1

    rng = np.random.default_rng(11)
    seen = {True: 0, False: 0}
    for _ in range(3000):
        b = rng.uniform(0.01, n * cell - 0.01, 2)
        ang = rng.uniform(-math.pi, math.pi)
        if rng.random() < 0.2:                     # along the grid's axes and diagonals
            ang = rng.integers(8) * math.pi / 4
        d = np.array([math.cos(ang), math.sin(ang)])
        reach = rng.uniform(0.0, 0.6)
        e = b + d * reach
        if not ((e > 0.001).all() and (e < n * cell - 0.001).all()):
            continue
        inside, outside = meets(b, e, 1e-9), meets(b, e, -1e-9)
        if inside != outside:                      # grazes the square: either answer
            continue
        got = test.walk(b[0], b[1], d[0], d[1], 0.0, reach, grid_array((0.0, 0.0, cell)))
        assert got == (not inside), (b, d, reach)
        seen[got] += 1
    assert seen[True] > 500 and seen[False] > 100
