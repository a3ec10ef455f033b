"""A crowd run (run.crowd, sim.loop.simulate_crowd) on small scenes built in code, with the
spine-only default rig: bodies never interpenetrate, a shade spot holds one creature, a prey
has one hunter; and the claims those rest on (behaviour.claims)."""

from __future__ import annotations

import dataclasses
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from baker.behaviour.claims import Claims
from baker.config import SIM_RATE_HZ, BakeConfig, load_rig_config, DEFAULT_RIG
from baker.context import Context
from baker.environment.model import Sun
from baker.navmesh import build
from baker import parallel
from baker.run import group
from baker.run.crowd import _Taken, crowd_separation, crowd_starts, run_crowd
from baker.locomotion.legs import folded_lever
from baker.run.follow import HOLD_MAX, Follower, measure_levers
from baker.sim.loop import simulate_crowd
from baker.streams import Streams
from test_navmesh_scenes import box, env_of, floor

RIG = load_rig_config(DEFAULT_RIG)
RIG = replace(RIG, legs=replace(RIG.legs, enabled=False))
BODY_RADIUS = max(RIG.body.width_profile)


def nav_of(env):
    return build(env, RIG.navigation)


def min_spine_gap(trajs) -> float:
    """The smallest distance between spine joints of different creatures over all frames."""
    sp = np.stack([t.spine_positions for t in trajs])          # (n, F, S, 3)
    n, F, S, _ = sp.shape
    own = np.repeat(np.arange(n), S)
    other = own[:, None] != own[None, :]
    return min(float(cdist(sp[:, f].reshape(-1, 3), sp[:, f].reshape(-1, 3))[other].min())
               for f in range(F))


def assert_same_fields(a, b) -> None:
    """Two dataclass records field for field, arrays bit for bit."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert x.tobytes() == y.tobytes() and x.shape == y.shape, f.name
        else:
            assert x == y, f.name


def overlapping(a, b) -> bool:
    return a["start"] < b["end"] and b["start"] < a["end"]


@pytest.fixture(scope="module")
def plane():
    env = env_of(floor(-0.6, 0.6, -0.6, 0.6))
    return env, nav_of(env)


def test_five_creatures_on_a_small_plane_never_interpenetrate():
    env = env_of(floor(-1.0, 1.0, -1.0, 1.0))
    nav = nav_of(env)
    cfg = BakeConfig(seconds=8.0, prey=0, rig=RIG, behaviour="wander")
    trajs = simulate_crowd(cfg, env, nav, 3, 5, Context())
    assert len(trajs) == 5 and all(t.n_frames == 241 for t in trajs)
    gap = min_spine_gap(trajs)
    assert gap >= 2.0 * BODY_RADIUS, gap
    # they move: every head walks at least a body length
    for t in trajs:
        walked = np.linalg.norm(np.diff(t.spine_positions[:, 0, [0, 2]], axis=0), axis=1).sum()
        assert walked > RIG.body.length


def test_a_dense_crowd_never_interpenetrates():
    """Sixteen creatures on a 1 m square: cornered heads turn on the spot and dither, and the
    cusps they leave are rounded off in the body's trail. With the body points sampled along
    the raw path (arc length), a head walked into another body here (spine joints 12.3 mm
    apart 13 s in); with the points where the solve puts the joints (run.crowd.Bodies), no
    spine joints come within two body radii."""
    env = env_of(floor(-0.5, 0.5, -0.5, 0.5))
    cfg = BakeConfig(seconds=16.0, prey=0, rig=RIG, behaviour="wander")
    trajs = simulate_crowd(cfg, env, nav_of(env), 4, 16, Context())
    gap = min_spine_gap(trajs)
    assert gap >= 2.0 * BODY_RADIUS, gap


def test_starts_keep_the_straight_start_lines_apart(plane):
    env, nav = plane
    sep = crowd_separation(RIG)
    starts = crowd_starts(nav, env, RIG, [Streams(1, creature=i) for i in range(6)], sep)
    back = np.linspace(1.05 * RIG.body.length, 0, 22)
    lines = [(s[None] - h[None] * back[:, None])[:, [0, 2]] for s, h in starts]
    for i in range(6):
        for j in range(i):
            assert cdist(lines[i], lines[j]).min() >= sep


def test_a_crowd_too_big_for_its_level_is_one_warning(caplog):
    """Starts that cannot keep apart (40 creatures on a 0.6 m square) are taken anyway, the
    nearest the draws found, and said once, not once a creature."""
    env = env_of(floor(0.0, 0.6, 0.0, 0.6))
    starts = crowd_starts(nav_of(env), env, RIG, [Streams(2, creature=i) for i in range(40)],
                          crowd_separation(RIG))
    assert len(starts) == 40
    records = [r for r in caplog.records if "start nearer another" in r.getMessage()]
    assert len(records) == 1 and records[0].getMessage().split()[2] == "40"


def _start_lines(starts) -> list[np.ndarray]:
    back = np.linspace(1.05 * RIG.body.length, 0, 22)
    return [s[None] - h[None] * back[:, None] for s, h in starts]


def _plan_gap(a: np.ndarray, b: np.ndarray) -> float:
    return float(cdist(a[:, [0, 2]], b[:, [0, 2]]).min())


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_starts_on_a_floor_above_another_are_not_in_its_way(seed, caplog):
    """A two-storey scene (a floor 0.4 m over the lower one, a ramp between): ten creatures
    start apart on each storey, some over one another, and no warning. The start lines were
    kept apart in plan only, so a line on the other floor was in the way: the starts said the
    level had little room for them (on every seed here), and on Three.js's tower level at 8x a
    crowd of 6 started two creatures side by side (0.23 m apart, 2 m bodies) that stayed
    locked together, each one's legs through the other's body in every frame."""
    from baker.run.crowd import crowd_band, crowd_reach
    from test_navmesh_scenes import quad

    env = env_of(floor(0.0, 0.4, 0.0, 0.6),
                 quad((0.4, 0, 0), (0.4, 0, 0.2), (1.1, 0.4, 0.2), (1.1, 0.4, 0)),
                 floor(1.1, 1.3, 0.0, 0.6, y=0.4), box((0.0, 0.38, 0.25), (1.1, 0.4, 0.6)))
    sep = crowd_separation(RIG)
    band = crowd_band(RIG, crowd_reach(RIG, sep, 1.0 / SIM_RATE_HZ))
    assert band < 0.38
    starts = crowd_starts(nav_of(env), env, RIG, [Streams(seed, creature=i) for i in range(10)],
                          sep, band=band)
    assert not [r for r in caplog.records if "start nearer another" in r.getMessage()]
    lines = _start_lines(starts)
    stacked = 0
    for i in range(len(lines)):
        for j in range(i):
            storey = abs(lines[i][0, 1] - lines[j][0, 1]) <= band
            assert not storey or _plan_gap(lines[i], lines[j]) >= sep
            stacked += not storey and _plan_gap(lines[i], lines[j]) < sep
    assert stacked


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_where_the_draws_find_no_room_the_level_is_searched_for_it(seed, caplog):
    """Twelve creatures in a 0.9 m room: the draws near the middle run out of room before the
    room does (the last creatures took the nearest of their draws, beside another, and the
    bake said the level had little room); the starts are then searched for over the whole
    surface (run.crowd._free_start), and every creature starts apart with its body line on
    walkable ground."""
    from baker.run import crowd

    env = env_of(floor(0.0, 0.9, 0.0, 0.9))
    nav = nav_of(env)
    sep = crowd_separation(RIG)
    streams = [Streams(seed, creature=i) for i in range(12)]
    starts = crowd_starts(nav, env, RIG, streams, sep)
    assert not [r for r in caplog.records if "start nearer another" in r.getMessage()]
    lines = _start_lines(starts)
    for i in range(len(lines)):
        assert nav.is_walkable(lines[i][1:]).all()
        for j in range(i):
            assert _plan_gap(lines[i], lines[j]) >= sep
    # the draws alone leave one near another
    free_start = crowd._free_start
    try:
        crowd._free_start = lambda *a, **k: None
        crowd_starts(nav, env, RIG, streams, sep)
    finally:
        crowd._free_start = free_start
    assert [r for r in caplog.records if "start nearer another" in r.getMessage()]


def test_the_first_creature_starts_where_a_lone_creature_does(plane):
    env, nav = plane
    from baker.run.start import choose_start

    alone = choose_start(nav, env, RIG.body.length, Streams(5).get("start"),
                         spread=RIG.wander.radius)
    first = crowd_starts(nav, env, RIG, [Streams(5, creature=i) for i in range(3)],
                         crowd_separation(RIG))[0]
    np.testing.assert_array_equal(first[0], alone[0])
    np.testing.assert_array_equal(first[1], alone[1])


def test_a_shade_spot_holds_one_creature():
    # a 0.26 m roof 0.4 m over the middle of a plane, the sun straight above: the shade deep
    # enough for a spot (SPOT_MARGIN all round) is a 0.16 m square, room for one spot
    env = env_of(floor(-0.6, 0.6, -0.6, 0.6), box((-0.13, 0.4, -0.13), (0.13, 0.42, 0.13)))
    env = replace(env, sun=Sun(np.array([0.0, 1.0, 0.0])))
    # (a roll of 8 or 9 sends a resting creature off to wander, so the spot can change hands)
    rig = replace(RIG, behaviour=replace(RIG.behaviour, shade_min_spots=1, shade_roll_max=7,
                                         decision_interval=2.0, shade_memory_interval=0.5,
                                         shade_sense_radius=0.12))
    cfg = BakeConfig(seconds=20.0, prey=0, rig=rig, behaviour="shade")
    recs, _ = run_crowd(cfg, env, nav_of(env), 1, 2, Context())
    rests = [[e for e in r.events if e["state"] == "rest_in_shade"] for r in recs]
    assert all(rests), "both creatures rest in the spot, one after the other"
    for a in rests[0]:
        for b in rests[1]:
            if overlapping(a, b):
                gap = np.linalg.norm(np.subtract(a["details"]["spot"], b["details"]["spot"]))
                assert gap >= rig.behaviour.shade_spot_spacing


def test_a_prey_has_one_hunter(plane):
    env, nav = plane
    cfg = BakeConfig(seconds=12.0, rig=RIG, behaviour="hunt", prey_positions=((0.0, 0.0, 0.3),))
    recs, prey = run_crowd(cfg, env, nav, 2, 2, Context())
    hunts = [[e for e in r.events if e["state"] in ("hunt", "strike", "feed")] for r in recs]
    assert any(hunts), "nobody hunted: the scene does not test the claim"
    for a in hunts[0]:
        for b in hunts[1]:
            assert not overlapping(a, b), (a, b)
    held = prey["prey_holder"][prey["prey_modes"] > 0]
    assert len(set(held.tolist()) - {-1}) <= 1


def test_claims():
    c = Claims(0.25)
    c.take_spot(0, np.zeros(3))
    assert c.spot_taken(np.array([0.1, 0.0, 0.0]), 1)
    assert not c.spot_taken(np.array([0.1, 0.0, 0.0]), 0)      # its own
    assert not c.spot_taken(np.array([0.3, 0.0, 0.0]), 1)
    c.free_spot(0)
    assert not c.spot_taken(np.zeros(3), 1)
    c.take_prey(1, "prey_01")
    assert c.hunter("prey_01") == 1
    c.free_prey(1)
    assert c.hunter("prey_01") is None


def test_a_crowd_of_one_is_a_lone_creature(plane):
    """simulate_crowd(n=1) gives simulate's trajectory bit for bit, a hunt and a feed included,
    so the pipeline can call it for every bake."""
    from baker.sim.loop import simulate

    env, nav = plane
    cfg = BakeConfig(seconds=10.0, rig=RIG, behaviour="hunt", prey_positions=((0.0, 0.0, 0.3),))
    alone = simulate(cfg, env, nav, Streams(2), Context())
    crowd = simulate_crowd(cfg, env, nav, 2, 1, Context())[0]
    assert (alone.prey_modes == 2).any()           # HELD: the prey is carried at the head
    assert_same_fields(alone, crowd)


def test_a_head_cornered_by_walking_bodies_holds_still_then_turns():
    # a head ringed by other creatures' body points, its path behind it: it would turn on the
    # spot, folding its trail into a cusp the body cannot follow; while those creatures walk
    # it holds still for them to move on (up to HOLD_MAX), then turns as a lone head does
    env = env_of(floor(0.0, 1.0, 0.0, 1.0))
    nav = nav_of(env)
    a = np.linspace(0.0, 2.0 * np.pi, 48, endpoint=False)
    ring = 0.5 + 0.7 * crowd_separation(RIG) * np.column_stack([np.cos(a), np.sin(a)])
    dt = 1.0 / SIM_RATE_HZ

    def cornered():
        f = Follower(nav, env.rays, nav.nearest([0.5, 0.0, 0.5]), np.array([1.0, 0.0, 0.0]), RIG)
        f.separation = crowd_separation(RIG)
        f.go(nav.nearest([0.1, 0.0, 0.5]))
        return f

    def steps(f, seconds, others, moving):
        for _ in range(int(round(seconds / dt))):
            f.others, f.others_move = others, moving
            f.step(dt)

    f = cornered()
    start, heading = f.head.base.copy(), f.head.heading.copy()
    steps(f, 0.9 * HOLD_MAX, ring, True)
    assert np.array_equal(f.head.base, start) and np.array_equal(f.head.heading, heading)
    steps(f, 0.2 * HOLD_MAX, ring, True)               # held long enough: it turns
    assert f.head.heading @ heading < np.cos(np.radians(20.0))
    # a ring of resting bodies: it turns without holding
    g = cornered()
    steps(g, 0.5 * HOLD_MAX, ring, False)
    assert g.head.heading @ heading < np.cos(np.radians(20.0)), g.head.heading
    steps(f, 12.0, None, False)                        # they have moved on: it walks its path
    assert np.hypot(*(f.head.base - [0.1, 0.0, 0.5])[[0, 2]]) < (
        RIG.locomotion.stopping_distance + 0.05)


def test_the_levers_measured_for_the_whole_crowd_are_each_creatures_own():
    """measure_levers casts every follower's lever rays in two batches ahead of the step; each
    lever is the one the follower measures on its own (bit for bit), and the step uses it.
    The legs are on (the lever bounds their speed) and a wall runs beside three creatures'
    paths, so many levers are folded (shorter than in the open)."""
    rig = load_rig_config(DEFAULT_RIG)
    env = env_of(floor(-1.0, 1.0, -1.0, 1.0), box((0.3, 0.0, -1.0), (0.4, 0.1, 0.6)))
    nav = build(env, rig.navigation)
    # three along the wall (at the eroded edge beside it), one in the open
    starts = [(0.29, -0.8), (0.29, -0.3), (0.25, 0.0), (-0.5, 0.2)]
    follows = [Follower(nav, env.rays, nav.nearest(np.array([x, 0.0, z])),
                        np.array([0.0, 0.0, 1.0]), rig) for x, z in starts]
    for f, (x, _) in zip(follows, starts):
        f.go(nav.nearest(np.array([0.29 if x > 0.0 else -0.3, 0.0, 0.8])))
    levers = []
    for _ in range(1200):
        asks = [(f, f.lever_request()) for f in follows]
        measure_levers(follows)
        for f, ask in asks:
            assert (ask is None) == (f._lever_ready is None)
            if ask is not None:
                ready, f._lever_ready = f._lever_ready, None
                assert ready[1] == f._leg_lever(*ask)          # measured on its own
                f._lever_ready = ready
                levers.append(ready[1])
        for f in follows:
            f.step(1.0 / SIM_RATE_HZ)
            assert f._lever_ready is None                        # used (or dropped) by the step
    open_ground = folded_lever(np.inf, rig.legs.reach, follows[0]._hip[0])
    assert len(levers) > 400 and (np.array(levers) < 0.8 * open_ground).sum() > 100


@pytest.mark.skipif(not parallel.can_fork(), reason="a peer process forks on Linux only")
@pytest.mark.parametrize("workers", [2, 3])
def test_a_crowd_run_on_several_processes_is_the_same_bits_as_on_one(monkeypatch, workers):
    """With two or more workers a crowd's followers are stepped in groups, all but one on
    forked peers (run.group): the records are the same bits as one process's, hunts, a feed
    and the neighbours' points handed over included."""
    monkeypatch.setattr(group, "available_cpus", lambda: workers)
    monkeypatch.setattr(group, "PER_PROCESS", 2)
    env = env_of(floor(-0.7, 0.7, -0.7, 0.7))
    nav = nav_of(env)
    cfg = BakeConfig(seconds=6.0, rig=RIG, behaviour="hunt",
                     prey_positions=((0.0, 0.0, 0.3), (-0.3, 0.0, -0.2)))
    peers = []
    real = group.Peer

    def counted(*a, **kw):
        peers.append(real(*a, **kw))
        return peers[-1]

    monkeypatch.setattr(group, "Peer", counted)
    one = run_crowd(cfg, env, nav, 6, 6, Context(), workers=1)
    assert not peers
    two = run_crowd(cfg, env, nav, 6, 6, Context(), workers=workers)
    assert len(peers) == workers - 1
    (a, pa), (b, pb) = one, two
    assert any(e["state"] == "feed" for r in a for e in r.events)
    for ra, rb in zip(a, b):
        assert_same_fields(ra, rb)
    for k in pa:
        assert np.array_equal(pa[k], pb[k]) if isinstance(pa[k], np.ndarray) else pa[k] == pb[k]


@pytest.mark.skipif(not parallel.can_fork(), reason="a peer process forks on Linux only")
def test_creatures_whose_peer_cannot_start_step_here_the_same(monkeypatch, plane, caplog):
    """A peer that cannot start (no more processes, no memory) leaves its creatures to this
    process, with a warning: the run is the one one process makes."""
    env, nav = plane
    monkeypatch.setattr(group, "available_cpus", lambda: 3)
    monkeypatch.setattr(group, "PER_PROCESS", 1)
    real, calls = group.Peer, []

    def second_fails(*a, **kw):
        calls.append(1)
        if len(calls) == 2:
            raise BlockingIOError(11, "Resource temporarily unavailable")
        return real(*a, **kw)

    monkeypatch.setattr(group, "Peer", second_fails)
    cfg = BakeConfig(seconds=2.0, prey=0, rig=RIG, behaviour="wander")
    three = run_crowd(cfg, env, nav, 1, 3, Context(), workers=3)[0]
    assert len(calls) == 2 and "could not start" in caplog.text
    for a, b in zip(run_crowd(cfg, env, nav, 1, 3, Context(), workers=1)[0], three):
        assert_same_fields(a, b)


def test_the_avoidance_test_is_every_point_measured_while_the_base_moves_on():
    """Follower._surface_test sorts the other bodies' points once per neighbour query (nearest the
    base where it first tests them) and skips, point by point, those too far to matter: as the
    base walks on between queries its answers stay those of measuring every point."""
    env = env_of(floor(0.0, 1.0, 0.0, 1.0))
    nav = nav_of(env)
    f = Follower(nav, env.rays, nav.nearest([0.5, 0.0, 0.5]), np.array([1.0, 0.0, 0.0]), RIG)
    f.separation = sep = crowd_separation(RIG)
    rng = np.random.default_rng(3)
    outcomes = set()
    for query in range(20):
        others = 0.5 + rng.uniform(-2.0 * sep, 2.0 * sep, (int(rng.integers(1, 60)), 2))
        for _ in range(4):                                  # the steps until the next query
            f.head.base = f.head.base + np.r_[rng.uniform(-0.004, 0.004), 0.0,
                                              rng.uniform(-0.004, 0.004)]
            f.others = others
            allowed = f._surface_test()
            b = f.head.base
            need = min(sep ** 2, float(((others - b[[0, 2]]) ** 2).sum(axis=1).min())) - 1e-12
            for x, z in b[[0, 2]] + rng.uniform(-0.06, 0.06, (200, 2)):
                every = bool((((others - [x, z]) ** 2).sum(axis=1) >= need).all())
                on_layer = not np.isnan(nav.layer_height(x, f.height, z, f.tol))
                assert allowed(x, z) == (every and on_layer)
                outcomes.add(every)
    assert outcomes == {True, False}


def test_the_start_gap_is_the_nearest_taken_point_over_every_line_taken():
    """crowd_starts measures a candidate start line against the lines already taken in a tree
    rebuilt every _Taken.RECENT points and the newest one by one: the gap is the least plan
    distance to any point taken within the storey band of its height (under the limit asked
    for; none: inf), as the distances to all of them give it."""
    rng = np.random.default_rng(4)
    band, limit = 0.5, 0.4
    taken, wide = _Taken(band), _Taken()
    points = np.zeros((0, 3))
    seen = set()
    for k in range(120):
        # a straight line a metre long on one of three storeys 3 m apart, a little sloped
        a, h = rng.uniform(0.0, 2.0 * np.pi), 3.0 * rng.integers(0, 3)
        line = (rng.uniform(0.0, 6.0, 3) * [1.0, 0.0, 1.0] + [0.0, h, 0.0]
                + np.linspace(0.0, 1.0, 23)[:, None] * [np.cos(a), rng.uniform(-0.3, 0.3),
                                                        np.sin(a)])
        if k:
            d = cdist(line[:, [0, 2]], points[:, [0, 2]])
            same = np.abs(line[:, 1][:, None] - points[:, 1][None, :]) <= band
            assert wide.gap(line) == pytest.approx(float(d.min()), abs=1e-12)
            d = d[same & (d < limit)]
            want = float(d.min()) if len(d) else np.inf
            assert taken.gap(line, limit) == pytest.approx(want, abs=1e-12)
            seen.add(np.isfinite(want))
        else:
            assert taken.gap(line, limit) == np.inf and wide.gap(line) == np.inf
        taken.add(line)
        wide.add(line)
        points = np.vstack([points, line])
    assert seen == {True, False}
    assert taken.tree is not None and 0 < taken.in_tree < len(points)
