"""The head's compiled surface test and turns (locomotion/contain.py) against the Python they
replace (navmesh.query.layer_height, HeadSteer's turns with a plain `allowed`, the follower's
line of sight walked with head.way_points): the same answers, bit for bit, on random patchy
layered grids, with and without other bodies' points to keep away from; and signals during
the direct (main-thread) calls stop them cleanly."""

from __future__ import annotations

import copy
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from signal_stops import assert_signals_stop_cleanly

from baker.config import SIM_RATE_HZ
from baker.locomotion import contain
from baker.locomotion.head import (_ARC_COS_SIN, _DEFLECT, _TIGHT_ARRAY, HeadSteer, grid_array,
                                   way_points)
from baker.navmesh.query import layer_height
from baker.navmesh.surface import DIRS

DT = 1.0 / SIM_RATE_HZ
CELL = 0.015
HERE = Path(__file__).resolve().parent


def patchy_grid(seed: int, n: int = 40, holes: float = 0.25):
    """A navigation grid as NavSurface.layer_height reads it (and its layer_height): n x n
    columns of CELL, each with 0-2 samples (a floor with holes, sloped a little, and a second
    storey over part of it)."""
    rng = np.random.default_rng(seed)
    origin = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)))
    pos, nrm, starts = [], [], [0]
    for ix in range(n):
        for iz in range(n):
            cx, cz = origin[0] + (ix + 0.5) * CELL, origin[1] + (iz + 0.5) * CELL
            if rng.random() < 0.3:                                  # an upper storey
                pos.append((cx, 0.2 + rng.normal(0, 0.003), cz))
                nrm.append(rng.normal((0.0, 1.0, 0.0), 0.1))
            if rng.random() > holes:
                pos.append((cx, rng.normal(0, 0.003), cz))
                nrm.append(rng.normal((0.0, 1.0, 0.0), 0.1))
            starts.append(len(pos))
    nrm = np.array(nrm).reshape(-1, 3)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    nav = SimpleNamespace(origin=origin, cell_size=CELL, shape=(n, n),
                          col_start=np.array(starts, dtype=np.int64),
                          positions=np.array(pos, dtype=np.float32).reshape(-1, 3),
                          normals=nrm.astype(np.float32), _cache={})
    nav.links = links_of(nav, 0.05)
    nav.layer_height = lambda x, y, z, tol: layer_height(nav, x, y, z, tol)
    return nav


def links_of(nav, step: float) -> np.ndarray:
    """(N, 8) links of the grid's samples: in each direction (navmesh.surface.DIRS), the sample
    of the neighbouring column nearest in height within `step`, else -1 (symmetric)."""
    n = nav.shape[1]
    cols, ys = nav.col_start, nav.positions[:, 1]
    links = np.full((len(ys), 8), -1, dtype=np.int32)
    for col in range(len(cols) - 1):
        ix, iz = divmod(col, n)
        for d, (ex, ez) in enumerate(DIRS.tolist()):
            jx, jz = ix + ex, iz + ez
            if not (0 <= jx < nav.shape[0] and 0 <= jz < n):
                continue
            other = range(cols[jx * n + jz], cols[jx * n + jz + 1])
            for k in range(cols[col], cols[col + 1]):
                dy = [abs(float(ys[j] - ys[k])) for j in other]
                if dy and min(dy) <= step:
                    links[k, d] = other[int(np.argmin(dy))]
    return links


def crowded(nav, rng, centre):
    """(near, ref, need) as Follower._surface_test sorts them: a few dozen body points round
    `centre`, sorted by distance from it."""
    pts = centre + rng.uniform(-0.06, 0.06, (int(rng.integers(1, 40)), 2))
    d2 = ((pts - centre) ** 2).sum(axis=1)
    order = np.argsort(d2, kind="stable")
    near = np.stack([np.sqrt(d2[order]) - 1e-6, pts[order, 0], pts[order, 1]], axis=1)
    return near, (float(centre[0]), float(centre[1])), min(0.023 ** 2, float(d2.min())) - 1e-12


def a_head(rng, nav, grid: bool) -> HeadSteer:
    lo = np.array(nav.origin) + 0.1
    x, z = rng.uniform(lo, lo + 0.4)
    yaw = rng.uniform(-math.pi, math.pi)
    head = HeadSteer(np.array([x, 0.0, z]), np.array([math.cos(yaw), 0.0, math.sin(yaw)]),
                     max_speed=0.2, turn_radius=0.0375, lead=0.0375, turn_rate=4.0,
                     amplitude=math.radians(25.0), max_offset=0.008, min_radius=0.009375)
    if grid:
        head.grid = (nav.origin[0], nav.origin[1], CELL)
    return head


def compiled_contain(head: HeadSteer, a, ang, step, test) -> tuple[float, float]:
    """HeadSteer._contain's turns by the kernel head_step calls (contain.contain), with its
    side effects on the head."""
    (hx, _, hz), (bx, _, bz) = head.heading.tolist(), head.base.tolist()
    h = np.array([hx, hz, bx, bz, a, ang, step, DT, head.tight_speed, head.min_radius,
                  head.turn_radius, head._u_side, float(head.hold), head.max_yaw_rate,
                  head._spun])
    out = np.empty(3)
    flags = contain.contain(*test.kernel_args(), h, grid_array(head.grid), *_ARC_COS_SIN,
                            _TIGHT_ARRAY, _DEFLECT, out)
    if flags & contain.SIDE:
        head._u_side = float(out[2])
    if flags & contain.HELD:
        head.held = True
    if flags & contain.CREPT:
        head._creep = 2.0 * head.min_radius
        head._spun += abs(out[0])
    return tuple(out[:2].tolist())


def compiled_more_room(head: HeadSteer, first, second, test) -> bool:
    """HeadSteer._more_room by the kernel head_step calls (contain.more_room)."""
    (hx, _, hz), (bx, _, bz) = head.heading.tolist(), head.base.tolist()
    return contain.more_room(*test.kernel_args(), hx, hz, bx, bz, first, second,
                             head.turn_radius, *_ARC_COS_SIN)


def test_the_compiled_layer_height_is_the_query_s():
    for seed in range(3):
        nav = patchy_grid(seed)
        cols, pos, nrm, p = contain.grid_arrays(nav)
        rng = np.random.default_rng(seed)
        lo = np.array(nav.origin)
        for x, z in rng.uniform(lo - 0.05, lo + 0.65, (3000, 2)):
            y, tol = float(rng.choice([0.0, 0.2, 0.1])), float(rng.choice([0.01, 0.15]))
            want = layer_height(nav, x, y, z, tol)
            got = contain.layer_height(cols, pos, nrm, p, x, y, z, tol)
            assert (math.isnan(want) and math.isnan(got)) or want == got


def test_the_compiled_slope_is_the_follower_s_python_slope():
    """contain.slope_grades (Follower._slope's rises, compiled) gives follow._grade's bits from
    the query's layer heights, missing probes (holes, other layers) and one-sided rises
    included."""
    from baker.run.follow import _grade

    kinds = set()
    for seed in range(3):
        nav = patchy_grid(seed)
        arrays = contain.grid_arrays(nav)
        rng = np.random.default_rng(10 + seed)
        lo = np.array(nav.origin)
        d = 2.0 * nav.cell_size
        for x, z in rng.uniform(lo - 0.05, lo + 0.65, (2000, 2)):
            y, tol = float(rng.choice([0.0, 0.2, 0.1])), float(rng.choice([0.01, 0.15]))
            hx = [layer_height(nav, x + s * d, y, z, tol) for s in (1, -1)]
            hz = [layer_height(nav, x, y, z + s * d, tol) for s in (1, -1)]
            want = (_grade(hx[0], y, hx[1], d), _grade(hz[0], y, hz[1], d))
            got = contain.slope_grades(*arrays, x, z, d, y, tol)
            for w, g in zip(want, got):
                assert (math.isnan(w) and math.isnan(g)) or w == g
            kinds.add(sum(h == h for h in hx))
    assert kinds == {0, 1, 2}           # both probes, one, none


@pytest.mark.parametrize("seed", range(4))
def test_compiled_turns_are_the_python_turns(seed):
    """HeadSteer._contain and _more_room compiled (the kernels head_step calls) and in Python
    with the same test: the same turn, step, U-turn side, hold and creep, bit for bit."""
    nav = patchy_grid(seed)
    rng = np.random.default_rng(100 + seed)
    seen = set()
    held_past_spin = 0
    for trial in range(400):
        grid = trial % 2 == 0
        one = a_head(rng, nav, grid)
        two = copy.deepcopy(one)
        y = 0.2 if trial % 5 == 0 else 0.0
        near = crowded(nav, rng, one.base[[0, 2]]) if trial % 3 else ()
        args = (nav, y, 0.05) + near
        fast, slow = contain.SurfaceTest(*args), contain.plain_test(*args)
        for h in (one, two):
            h._u_side = float(rng.choice([0.0, 1.0, -1.0]))
            h.hold = trial % 4 == 0
            # turned on the spot already: none, some, all but a sliver of contain.SPIN
            h._spun = float(rng.choice([0.0, 0.5, contain.SPIN - 1e-3]))
        two._u_side, two.hold, two._spun = one._u_side, one.hold, one._spun
        spun = one._spun
        ang = float(rng.uniform(-math.pi, math.pi))
        a = float(np.clip(ang, -0.05, 0.05))
        step = float(rng.choice([0.2 * DT, 0.05 * DT, 0.25 * DT]))
        got = compiled_contain(one, a, ang, step, fast)
        want = two._contain(a, ang, step, DT, slow)
        assert got == want
        assert ((one._u_side, one.held, one._creep, one._spun)
                == (two._u_side, two.held, two._creep, two._spun))
        if one.held and not one.hold:
            held_past_spin += 1     # cornered among other bodies with its turn used up
            assert near and spun > 0.0
        for side in (1.0, -1.0):
            assert compiled_more_room(one, side, -side, fast) == two._more_room(side, -side, slow)
        seen.add((got == (a, step), one.held, one._creep > 0.0))
    assert len(seen) >= 3          # the wanted turn, other turns, and holds or turns on the spot
    assert held_past_spin > 0


def test_compiled_heads_walk_the_python_heads_steps():
    """Whole walks: two heads chasing the same agent over patchy ground, one with a SurfaceTest
    (its whole step compiled, contain.head_step) and one with the Python test (head.py's
    step), stay bit for bit the same, aiming at a point at times, with the agent stopped at
    times, under a speed cap and other slither rates."""
    nav = patchy_grid(7, n=60, holes=0.35)
    rng = np.random.default_rng(7)
    for walk in range(6):
        one = a_head(rng, nav, walk % 2 == 0)
        two = copy.deepcopy(one)
        lo = np.array(nav.origin)
        for k in range(600):
            if k % 150 == 0:
                ax, az = rng.uniform(lo + 0.05, lo + 0.85)
            agent = np.array([ax, 0.0, az])
            aim = None
            if k % 200 > 120:            # at times an aim point almost straight ahead (a turn
                hx, _, hz = one.heading  # smaller than a step's largest)
                aim = one.base + [0.08 * hx + 0.0005 * hz, 0.0, 0.08 * hz - 0.0005 * hx]
            speed = 0.0 if k % 150 > 130 else 0.2                         # the agent stopped
            one.speed_cap = two.speed_cap = math.inf if k % 100 < 70 else 0.05
            one.turn_rate_scale = two.turn_rate_scale = 1.0 + (k % 3) * 0.5
            for h, test in ((one, contain.SurfaceTest(nav, 0.0, 0.05)),
                            (two, contain.plain_test(nav, 0.0, 0.05))):
                h.step(DT, agent, speed, allowed=test, aim=aim)
            for name in ("base", "heading", "position", "sway_dir"):
                assert getattr(one, name).tobytes() == getattr(two, name).tobytes(), name
            assert ((one.phase, one.lateral_amp, one.speed, one._u_side, one._creep, one.held,
                     one._spun)
                    == (two.phase, two.lateral_amp, two.speed, two._u_side, two._creep, two.held,
                        two._spun))


def test_the_compiled_line_of_sight_is_the_python_walk():
    """contain.line_clear against the follower's walk in Python (head.way_points, the height
    continued point by point), and contain.way_points against head.way_points."""
    nav = patchy_grid(11)
    cols, pos, nrm, p = contain.grid_arrays(nav)
    rng = np.random.default_rng(11)
    lo = np.array(nav.origin)
    outcomes = set()
    for trial in range(2000):
        grid = (nav.origin[0], nav.origin[1], CELL) if trial % 3 else None
        (bx, bz), (qx, qz) = rng.uniform(lo, lo + 0.6, (2, 2))
        dx, dz = qx - bx, qz - bz
        n = math.hypot(dx, dz)
        y = 0.0
        want = True
        for r in way_points(bx, bz, dx / n, dz / n, 0.0, n, grid):
            y = layer_height(nav, bx + r * dx / n, y, bz + r * dz / n, 0.05)
            if y != y:
                want = False
                break
        got = contain.line_clear(cols, pos, nrm, p, bx, bz, dx, dz, n, 0.0, 0.05,
                                 grid_array(grid))
        assert got == want
        outcomes.add(got)
        s = float(rng.uniform(0.0, 0.5 * n))
        py = way_points(bx, bz, dx / n, dz / n, s, n, grid)
        out = np.empty(contain.crossings_bound(s, n, grid_array(grid)))
        k = contain.way_points_into(bx, bz, dx / n, dz / n, s, n, grid_array(grid), out)
        assert out[:k].tolist() == py
    assert outcomes == {True, False}


def test_signals_during_the_direct_compiled_calls_stop_cleanly():
    """The kernels are called on the main thread: 100 SIGTERMs at staggered moments, each
    raising there, during repeated calls of each stop them cleanly (an array returned would
    crash the process, parallel.off_main_thread)."""
    assert_signals_stop_cleanly("""
        import sys, math
        sys.path[:0] = [%r, %r]
        from test_head_compiled import (patchy_grid, crowded, a_head, DT, compiled_contain,
                                        compiled_more_room)
        from baker.locomotion import contain
        nav = patchy_grid(3)
        rng = np.random.default_rng(3)
        head = a_head(rng, nav, True)
        test = contain.SurfaceTest(nav, 0.0, 0.05, *crowded(nav, rng, head.base[[0, 2]]))
        compiled_contain(head, 0.05, 3.0, 0.2 * DT, test)  # compiled (or loaded) before the signals
        compiled_more_room(head, 1.0, -1.0, test)
        test(head.base[0], head.base[2])
        """ % (str(HERE), str(HERE.parent / "tools")), """
        compiled_contain(head, 0.05, 3.0, 0.2 * DT, test)
        compiled_more_room(head, 1.0, -1.0, test)
        test(head.base[0], head.base[2])
        """, times=100)


def test_ready_compiles_every_direct_kernel_for_the_grid_s_array_types():
    """contain.ready compiles (off the main thread) each kernel the run calls directly for the
    grid's array types, read-only ones (a memory-mapped cache's) included, so no call compiles
    on the main thread, where a signal would land inside LLVM's callbacks."""
    from numba import typeof

    for writeable in (True, False):
        nav = patchy_grid(5)
        for a in (nav.col_start, nav.positions, nav.normals):
            a.flags.writeable = writeable
        contain.ready(nav)
        types = tuple(typeof(a) for a in contain.grid_arrays(nav)[:3])
        for kernel in (contain._allowed, contain.contain, contain.more_room, contain.line_clear,
                       contain.layer_height, contain.head_step, contain.slope_grades):
            assert any(tuple(sig[:3]) == types for sig in kernel.signatures), kernel


def test_the_compiled_hypot_is_python_s_bit_for_bit():
    """contain.hypot (the kernels' distance) against math.hypot over scales from subnormal to
    huge, and the special values (numba's own math.hypot, the C library's, differs from
    Python's in about 0.2 % of such pairs)."""
    rng = np.random.default_rng(5)
    n = 40_000
    # below 2**-1024 CPython 3.12 computes differently from 3.11 (whose code contain.hypot is)
    tiny = (1e-310,) if sys.version_info[:2] == (3, 11) else ()
    for scale in (*tiny, 1e-300, 1e-3, 1.0, 1e3, 1e300):
        a = rng.normal(0.0, scale, n)
        b = rng.normal(0.0, scale, n) * rng.choice([1.0, 1e-4, 1e4, 0.0, -1.0], n)
        for x, y in zip(a.tolist(), b.tolist()):
            assert contain.hypot(x, y) == math.hypot(x, y), (x, y)
    for x, y in [(0.0, -0.0), (math.inf, math.nan), (-math.inf, 1.0), (1e308, 1e308),
                 (3.0, 4.0), (2.2250738585072014e-308, 1e-310)]:
        assert contain.hypot(x, y) == math.hypot(x, y)
    assert math.isnan(contain.hypot(math.nan, 1.0))


@pytest.mark.parametrize("compiled", [False, True])
def test_among_other_bodies_a_cornered_head_turns_at_most_spin_on_the_spot(compiled):
    """A head walled in ahead and to both sides by other bodies' points, its agent straight
    behind it on open floor: it turns on the spot toward the agent by at most contain.SPIN (a
    right angle; a sharper corner is a cusp the body jumps across), then holds."""
    nav = patchy_grid(11, n=60, holes=0.0)
    x0, z0 = nav.origin[0] + 0.45, nav.origin[1] + 0.45
    head = HeadSteer(np.array([x0, 0.0, z0]), np.array([0.0, 0.0, 1.0]), max_speed=0.2,
                     turn_radius=0.0375, lead=0.0375, turn_rate=4.0,
                     amplitude=math.radians(25.0), max_offset=0.008, min_radius=0.009375)
    # a half ring of body points 1.5 cm ahead of the head, from one side round to the other
    arc = np.linspace(-0.5 * math.pi, 0.5 * math.pi, 60)
    pts = np.stack([x0 + 0.015 * np.sin(arc), z0 + 0.015 * np.cos(arc)], axis=1)
    d2 = ((pts - [x0, z0]) ** 2).sum(axis=1)
    order = np.argsort(d2, kind="stable")
    near = np.stack([np.sqrt(d2[order]) - 1e-6, pts[order, 0], pts[order, 1]], axis=1)
    need = min(0.08 ** 2, float(d2.min())) - 1e-12
    agent = np.array([x0, 0.0, z0 - 0.2])
    turned, held = 0.0, []
    for _ in range(400):
        make = contain.SurfaceTest if compiled else contain.plain_test
        test = make(nav, 0.0, 0.05, near, (x0, z0), need)
        h0 = head.heading.copy()
        head.step(DT, agent, 0.2, allowed=test)
        assert head.base[0] == x0 and head.base[2] == z0           # never walks into the ring
        turned += math.acos(min(1.0, float(np.dot(h0, head.heading))))
        held.append(head.held)
    assert 0.5 * math.pi - 0.05 < turned <= contain.SPIN + 1e-9
    assert all(held[-200:])                 # the turn used up: held since
