"""The head's turns where the walkable surface leaves no room for its turning circle
(locomotion/head.py HeadSteer._contain): on circles of at least min_radius, slowed, never a sharp
deflection at full speed or a turn on the spot while a tight circle fits. The trail of such a
reversal is a loop the spine's chord placement (locomotion/body.py place_chain) follows. Sharp
deflections a few steps apart folded the trail into a cusp narrower than a spacing: the chord
found the joint behind on the far side of the fold one frame and at its tip the next (showcase
103049: a trunk joint jumped two spacings in a frame, the next turned 46 degrees).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from baker.config import SIM_RATE_HZ
from baker.geometry import polyline
from baker.locomotion.body import Trail, place_chain
from baker.locomotion.head import HeadSteer, way_end, way_points

DT = 1.0 / SIM_RATE_HZ
TURN_RADIUS = 0.0375     # the default rig's: 3 spacings
MIN_RADIUS = 0.009375    # 0.75 spacings
SPACING, SEGMENTS = 0.0125, 21


def corridor(width: float, length: float = 0.3):
    """A dead-end strip 0 <= x <= length, |z| <= width / 2 (the eroded walkable surface)."""
    def allowed(x: float, z: float) -> bool:
        return 0.0 <= x <= length and abs(z) <= 0.5 * width
    return allowed


def u_turn(width: float, min_radius: float | None = MIN_RADIUS, seconds: float = 2.0,
           z0: float = 0.0, heads: list | None = None):
    """A head walking +x down the strip from (0.2, z0) toward its dead end, with the agent
    behind it: returns (base positions, headings, step lengths) per step, and appends the
    head's positions (slither included) to `heads`."""
    head = HeadSteer(np.array([0.2, 0.0, z0]), np.array([1.0, 0.0, 0.0]), max_speed=0.2,
                     turn_radius=TURN_RADIUS, lead=TURN_RADIUS, turn_rate=4.0,
                     amplitude=math.radians(25.0), max_offset=0.008, min_radius=min_radius)
    allowed = corridor(width)
    agent = np.array([0.05, 0.0, 0.0])
    base, heading = [head.base.copy()], [head.heading.copy()]
    for _ in range(int(seconds / DT)):
        head.step(DT, agent, 0.2, allowed=allowed)
        if heads is not None:
            heads.append(head.position.copy())
        base.append(head.base.copy())
        heading.append(head.heading.copy())
    base, heading = np.array(base), np.array(heading)
    steps = np.linalg.norm(np.diff(base, axis=0), axis=1)
    return base, heading, steps


@pytest.mark.parametrize("width", [0.025, 0.03, 0.05, 0.07])
def test_a_reversal_in_a_narrow_dead_end_turns_on_circles_of_at_least_min_radius(width):
    allowed = corridor(width)
    base, heading, steps = u_turn(width)
    assert all(allowed(x, z) for x, z in base[:, [0, 2]])         # on the surface throughout
    assert heading[:, 0].min() < -0.9                             # turned back
    turn = np.arccos(np.clip(np.einsum("ij,ij->i", heading[:-1], heading[1:]), -1.0, 1.0))
    moving = steps > 1e-12
    # every step turns no more sharply than the tight circle allows ...
    assert np.all(turn[moving] <= steps[moving] / MIN_RADIUS + 1e-9)
    # ... and the head never turns on the spot while the tight circle fits the strip
    assert not np.any(turn[~moving] > 1e-12)


def test_without_a_tight_circle_the_same_reversal_turns_sharper():
    """The bound is what the head does, not what the strip allows: a head whose tightest
    circle is its usual one cannot turn round in a 3 cm strip without turning on the spot."""
    base, heading, steps = u_turn(0.03, min_radius=None)
    turn = np.arccos(np.clip(np.einsum("ij,ij->i", heading[:-1], heading[1:]), -1.0, 1.0))
    assert np.any(turn[steps <= 1e-12] > 1e-12)


def chain_jumps(path: np.ndarray, start: np.ndarray, fps: int = 30) -> float:
    """The largest per-frame move of any trunk joint beyond the head's own [spacings], for a
    spine placed by chord (place_chain) on the head's path (n, 3) stepped at SIM_RATE_HZ, on
    flat ground, behind a straight start line ending at `start` along +x."""
    line = start - np.array([1.0, 0.0, 0.0]) * np.linspace(0.3, 0.0, 200)[:-1, None]
    pts = np.vstack([line, path])
    pts[:, 1] = 0.0
    cum = polyline.arc_lengths(pts)
    keep = np.r_[True, np.diff(cum) > 1e-9]
    n = int(keep.sum())
    trail = Trail(points=pts[keep], normals=np.tile([0.0, 1.0, 0.0], (n, 1)),
                  ground=np.zeros(n), cum=cum[keep], cum_h=cum[keep].copy())
    head = cum[len(line):][:: SIM_RATE_HZ // fps]
    pos, _ = place_chain(trail, head, np.zeros((len(head), SEGMENTS)), SPACING)
    move = np.linalg.norm(np.diff(pos, axis=0), axis=2)
    return float((move[:, 1:] - move[:, :1]).max() / SPACING)


@pytest.mark.parametrize("width", [0.02, 0.025, 0.03, 0.04, 0.05, 0.07])
@pytest.mark.parametrize("z0", [-0.3, 0.0, 0.3])
def test_the_spine_follows_a_reversal_in_a_narrow_dead_end_without_a_joint_jumping(width, z0):
    """(Before the tight circles, 15 of these 18 reversals made a trunk joint jump 0.5 to 1.5
    spacings more than the head moved in a frame; now the most is 0.09.)"""
    heads: list = []
    u_turn(width, seconds=1.5, z0=z0 * width, heads=heads)
    assert chain_jumps(np.array(heads), np.array([0.2, 0.0, z0 * width])) < 0.25


CELL = 0.015
BLOCK = (0.0, 0.0)      # the lower corner (x, z) of the one blocked grid column


def one_blocked_column(x: float, z: float) -> bool:
    """Open ground but for one grid column, as an eroded surface marks a column a pebble or a
    spike stands in (the surface test answers per column of a CELL grid)."""
    return not (BLOCK[0] <= x < BLOCK[0] + CELL and BLOCK[1] <= z < BLOCK[1] + CELL)


def past_a_column(offset: float, speed: float, grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A head walking -z toward the blocked column, `offset` metres right of its left edge
    (inside its width), while the agent it chases walks -z along that edge (a path pulled tight
    round the column's corner). Returns (head positions, base headings, base step lengths)."""
    head = HeadSteer(np.array([offset + 0.004, 0.0, 0.06]), np.array([-0.1, 0.0, -1.0]),
                     max_speed=0.2, turn_radius=TURN_RADIUS, lead=TURN_RADIUS, turn_rate=4.0,
                     amplitude=math.radians(25.0), max_offset=0.008, min_radius=MIN_RADIUS)
    head.grid = grid
    heads, heading, steps = [], [], []
    for k in range(int(1.5 / DT)):
        agent = np.array([0.0, 0.0, 0.06 - TURN_RADIUS - speed * k * DT])
        b = head.base.copy()
        head.step(DT, agent, speed, allowed=one_blocked_column)
        heads.append(head.position.copy())
        heading.append(head.heading.copy())
        steps.append(float(np.linalg.norm(head.base - b)))
    return np.array(heads), np.array(heading), np.array(steps)


@pytest.mark.parametrize("speed", [0.06, 0.15])
@pytest.mark.parametrize("offset", [0.0003, 0.0006, 0.001, 0.002, 0.004])
def test_a_head_cutting_a_corner_turns_off_before_the_column_instead_of_on_the_spot(offset, speed):
    """A look-ahead tested only at its far end saw past the column's corner: the head walked
    on into the corner, had no room left for a tight circle and turned round on the spot, a
    cusp in the trail that folded the tail over 15 s later (default 112610: 44 degrees in a
    frame). Tested in every column the way crosses, it slides off along the column's edge."""
    heads, heading, steps = past_a_column(offset, speed, (0.0, 0.0, CELL))
    turn = np.arccos(np.clip(np.einsum("ij,ij->i", heading[:-1], heading[1:]), -1.0, 1.0))
    assert not np.any(turn[steps[1:] <= 1e-12] > 1e-12)           # never on the spot
    assert heads[-1][2] < -CELL                                    # and on past the column


def test_way_points_fall_in_every_column_the_way_crosses():
    # a way from column (0, 0) to (1, 1) that clips the corner of column (0, 1) for 0.1 mm
    x0, z0, d = 0.0, 0.0148, np.array([0.0149, 0.0002])
    d = d / np.linalg.norm(d)
    pts = way_points(x0, z0, d[0], d[1], 0.001, 0.03, (0.0, 0.0, CELL))
    cols = [(math.floor((x0 + d[0] * r) / CELL), math.floor((z0 + d[1] * r) / CELL)) for r in pts]
    assert cols == [(0, 1), (1, 1)]          # the first column is the step's, tested apart
    assert pts[-1] == 0.03 and all(0.001 < r <= 0.03 for r in pts)
    # without a grid: LOOK_SAMPLES even steps
    assert way_points(x0, z0, d[0], d[1], 0.001, 0.03, None)[0] == pytest.approx(0.001 + 0.029 / 8)


@pytest.mark.parametrize("seed", range(3))
def test_the_room_comparison_stops_early_with_the_whole_walks_answer(seed):
    """_more_room walks the second circle only until the comparison is known: on random
    patchy ground, random bases and headings, its answer is that of the two whole walks."""
    rng = np.random.default_rng(seed)
    blocked = rng.random((40, 40)) < 0.15

    def patchy(x: float, z: float) -> bool:
        i, j = math.floor(x / 0.005) + 20, math.floor(z / 0.005) + 20
        return 0 <= i < 40 and 0 <= j < 40 and not blocked[i, j]

    decided = set()
    for _ in range(300):
        heading = rng.normal(size=3) * [1.0, 0.0, 1.0]
        head = HeadSteer(np.r_[rng.uniform(-0.05, 0.05), 0.0, rng.uniform(-0.05, 0.05)],
                         heading / np.linalg.norm(heading), max_speed=0.2,
                         turn_radius=TURN_RADIUS, lead=TURN_RADIUS, turn_rate=4.0,
                         amplitude=math.radians(25.0), max_offset=0.008, min_radius=MIN_RADIUS)
        for radius in (None, MIN_RADIUS):
            whole = [head._circle_room(sd, patchy, radius) for sd in (1.0, -1.0)]
            assert head._more_room(1.0, -1.0, patchy, radius) == (whole[1] > whole[0])
            decided.add(whole[1] > whole[0])
    assert decided == {True, False}


def test_the_look_aheads_end_is_way_points_last():
    """free tests a look-ahead's end before the rest (way_end): it must be way_points' last
    distance, bit for bit, with and without a grid, and None where there are none."""
    rng = np.random.default_rng(5)
    for _ in range(2000):
        x, z, s = rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.0, 0.02)
        reach = s + rng.choice([-0.01, 0.0, rng.uniform(0.0, 0.05)])
        ang = rng.uniform(0, 2 * math.pi)
        for grid in (None, (rng.uniform(-1, 0), rng.uniform(-1, 0), rng.choice([CELL, 0.003]))):
            way = way_points(x, z, math.cos(ang), math.sin(ang), s, reach, grid)
            end = way_end(s, reach, grid)
            assert (end is None) == (not way)
            assert end is None or end == way[-1]
