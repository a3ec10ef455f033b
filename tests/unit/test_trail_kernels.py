"""The compiled trail passes (locomotion.trail_kernels) give the same bits as the numpy and
scipy calls they replace: np.interp on rows shifted apart, scipy's gaussian_filter1d with mode
"nearest" after straight_ended_smooth's straight ends, the whole trail_ends against its numpy
form, and body.place_chain against its numpy form (both kept here as the references), on
random rows with flat stretches, keys outside the knots, short lines, dithering heads and
trails that fold back on themselves."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from baker.geometry import polyline
from baker.geometry.transforms import length
from baker.locomotion import trail_kernels as tk
from baker.locomotion.trail_kernels import FARTHER
from baker.locomotion.body import (RAISED_RISE, ROUND, Trail, _row_shifts, place_chain,
                                   straight_ended_smooth, trail_ends)

SPACING = 0.0125


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def numpy_interp_rows(x, xp, fp):
    """trail_ends' row interpolation as numpy computed it: the rows shifted apart, one flat
    np.interp per component."""
    x = np.clip(x, xp[:, :1], xp[:, -1:])
    width = float((xp[:, -1] - xp[:, 0]).max()) + 1.0
    shift = (width * np.arange(len(x)) - xp[:, 0])[:, None]
    flat_x, flat_xp = (x + shift).ravel(), (xp + shift).ravel()
    return np.stack([np.interp(flat_x, flat_xp, fp[..., k].ravel()).reshape(x.shape)
                     for k in range(fp.shape[2])], axis=-1)


def numpy_trail_ends(paths, cums, ends, extent, spacing, res):
    """trail_ends in numpy and scipy (the code the kernels replaced)."""
    sigma = ROUND * spacing / res
    pad = int(4.0 * max(sigma, 2.0 * spacing / res) + 0.5)
    n = len(paths)
    rows = np.arange(n)
    total = cums[rows, ends]
    span = np.full(n, 2.0 * extent + 2.0 * pad * res)
    m = max(int(np.ceil(extent / res)), 1) + 1
    out = np.empty((n, m, 3))
    todo = rows
    while len(todo):
        w = int(np.ceil(span[todo[0]] / res)) + 1
        s = total[todo, None] + np.linspace(-span[todo[0]], 0.0, w)[None, :]
        pts = numpy_interp_rows(np.maximum(s, 0.0),
                                np.where(np.arange(cums.shape[1]) <= ends[todo, None],
                                         cums[todo], total[todo, None]), paths[todo])
        k = min(pad, w - 1)
        pts[..., [0, 2]] = straight_ended_smooth(pts[..., [0, 2]], sigma, axis=1, reach=pad)
        pts[..., 1] = gaussian_filter1d(pts[..., 1], 2.0 * spacing / res, axis=1,
                                        mode="nearest")
        arc = np.concatenate([np.zeros((len(todo), 1)),
                              np.cumsum(length(np.diff(pts, axis=1)), axis=1)], axis=1)
        short = (s[:, 0] > 0.0) & (arc[:, -1] - arc[:, k] < extent)
        done = ~short
        q = arc[done, -1:] + np.linspace(-extent, 0.0, m)[None, :]
        out[todo[done]] = numpy_interp_rows(q, arc[done], pts[done])
        todo = todo[short]
        span[todo] *= 2.0
    return out


def knots(rng, n, b):
    """(n, b) non-decreasing rows with flat stretches (repeated knots) and their values
    (n, b, 3)."""
    steps = rng.exponential(0.01, (n, b)) * (rng.random((n, b)) > 0.2)
    xp = np.cumsum(steps, axis=1) + rng.uniform(-1.0, 5.0, (n, 1))
    return xp, rng.normal(size=(n, b, 3)) * rng.choice([1e-3, 1.0, 50.0], (n, 1, 1))


@pytest.mark.parametrize("seed", range(8))
def test_interp_rows_gives_numpy_interps_bits(seed):
    rng = np.random.default_rng(seed)
    n, b, a = int(rng.integers(1, 9)), int(rng.integers(2, 200)), int(rng.integers(1, 300))
    xp, fp = knots(rng, n, b)
    lo, hi = xp[:, :1], xp[:, -1:]
    x = lo + (hi - lo) * rng.uniform(-0.2, 1.2, (n, a))
    x[:, :a // 3] = np.sort(x[:, :a // 3], axis=1)      # rising keys, then any order
    h = a // 4                                            # the last keys on knots
    if h:
        x[:, a - h:] = np.take_along_axis(xp, rng.integers(0, b, (n, h)), axis=1)
    out = np.empty((n, a, 3))
    tk.interp_rows(x, xp, fp, _row_shifts(xp), out)
    np.testing.assert_array_equal(bits(out), bits(numpy_interp_rows(x, xp, fp)))


@pytest.mark.parametrize("sigma", [0.5, 1.0, 2.4, 6.0, 8.0])
@pytest.mark.parametrize("n", [1, 2, 5, 40, 313])
def test_smoothing_gives_scipys_bits(sigma, n):
    rng = np.random.default_rng(int(sigma * 10) + n)
    line = np.cumsum(rng.normal(size=n)) * rng.choice([1e-3, 1.0, 100.0])
    wts = tk.gaussian_weights(sigma)
    r = (len(wts) - 1) // 2
    for k in sorted({0, min(1, n - 1), min(3, n - 1), min(r + 2, n - 1), n - 1}):
        out = np.empty(n)
        tk._smooth(line, wts, k, np.empty(n + 2 * k + 2 * r), out)
        want = (gaussian_filter1d(line, sigma, mode="nearest") if k < 1 else
                straight_ended_smooth(line, sigma, reach=k))
        np.testing.assert_array_equal(bits(out), bits(want), err_msg=f"k={k}")


def head_path(rng, T, dither: bool):
    """(T, 3) a wandering head path (a step of a few millimetres), dithering back and forth
    over its middle when `dither`, and its horizontal arc lengths."""
    turn = np.cumsum(rng.normal(0.0, 0.3, T))
    step = rng.uniform(0.0, 0.004, T) * (rng.random(T) > 0.1)
    if dither:
        a, b = T // 3, 2 * T // 3
        turn[a:b] += np.pi * (np.arange(b - a) % 6 < 3)
    xz = np.cumsum(np.stack([np.cos(turn) * step, np.sin(turn) * step], 1), axis=0)
    path = np.column_stack([xz[:, 0], rng.normal(0.0, 0.002, T).cumsum() * 0.1, xz[:, 1]])
    d = np.diff(path[:, [0, 2]], axis=0)
    return path, np.r_[0.0, np.cumsum(np.hypot(d[:, 0], d[:, 1]))]


@pytest.mark.parametrize("seed", range(6))
def test_trail_ends_gives_the_numpy_forms_bits(seed):
    rng = np.random.default_rng(100 + seed)
    n, T = int(rng.integers(1, 12)), int(rng.integers(20, 900))
    paths, cums = np.zeros((n, T, 3)), np.zeros((n, T))
    ends = rng.integers(1, T, n)
    for i in range(n):
        p, c = head_path(rng, T, dither=bool(i % 2))
        paths[i], cums[i] = p, c
    extent = float(rng.uniform(5, 30)) * SPACING
    for res in (0.25 * SPACING, SPACING / 8.0):
        got = trail_ends(paths, cums, ends, extent, SPACING, res)
        want = numpy_trail_ends(paths, cums, ends, extent, SPACING, res)
        np.testing.assert_array_equal(bits(got), bits(want))


@pytest.mark.parametrize("seed", range(6))
def test_trail_ends_read_in_place_give_the_copied_windows_bits(seed):
    """trail_ends on rows of kept paths from their starts (rows, starts: the paths read where
    they lie, run.crowd.Bodies) gives the bits of trail_ends on copies of those windows, their
    arc lengths from the start and held at the head's after it (what the crowd copied before)."""
    rng = np.random.default_rng(200 + seed)
    N, T = int(rng.integers(2, 14)), int(rng.integers(40, 900))
    paths, cums = np.zeros((N, T, 3)), np.zeros((N, T))
    for i in range(N):
        paths[i], cums[i] = head_path(rng, T, dither=bool(i % 2))
    rows = rng.choice(N, int(rng.integers(1, N + 1)), replace=False)
    ends = rng.integers(1, T, len(rows))
    starts = (ends * rng.uniform(0.0, 1.0, len(rows))).astype(np.intp)
    size = int((ends + 1 - starts).max())
    at = np.minimum(starts[:, None] + np.arange(size), ends[:, None])
    windows = paths[rows[:, None], at]
    arcs = cums[rows[:, None], at] - cums[rows, starts][:, None]
    extent = float(rng.uniform(5, 30)) * SPACING
    for res in (0.25 * SPACING, SPACING / 8.0):
        got = trail_ends(paths, cums, ends, extent, SPACING, res, rows=rows, starts=starts)
        want = trail_ends(windows, arcs, np.full(len(rows), size - 1), extent, SPACING, res)
        np.testing.assert_array_equal(bits(got), bits(want))


def test_first_at_or_above_is_searchsorted():
    rng = np.random.default_rng(3)
    for _ in range(100):
        N, T = 5, int(rng.integers(1, 50))
        cum = np.sort(rng.integers(0, 20, (N, T)).astype(float), axis=1)
        rows, ends = rng.integers(0, N, 7), rng.integers(0, T, 7)
        values = rng.integers(-2, 22, 7).astype(float)
        want = [np.searchsorted(cum[i, :j + 1], x) for i, j, x in zip(rows, ends, values)]
        np.testing.assert_array_equal(tk.first_at_or_above(cum, rows, ends, values), want)


def test_weights_are_scipys_kernel():
    from scipy.ndimage import correlate1d

    rng = np.random.default_rng(7)
    line = rng.normal(size=60)
    for sigma in (0.7, 3.0, 6.0):
        np.testing.assert_array_equal(
            bits(correlate1d(line, tk.gaussian_weights(sigma), mode="nearest")),
            bits(gaussian_filter1d(line, sigma, mode="nearest")))


def test_signals_during_the_direct_compiled_calls_stop_cleanly():
    """After their first call (compiled off the main thread) the kernels are called on the
    main thread: 100 SIGTERMs at staggered moments, each raising there, during repeated
    trail_ends stop them cleanly (parallel.off_main_thread: a result boxed there crashed)."""
    from signal_stops import assert_signals_stop_cleanly

    assert_signals_stop_cleanly("""
        import sys
        sys.path[:0] = [%r]
        from test_trail_kernels import head_path, SPACING
        from baker.locomotion.body import trail_ends
        rng = np.random.default_rng(5)
        paths, cums = zip(*(head_path(rng, 600, dither=bool(i %% 2)) for i in range(8)))
        paths, cums = np.stack(paths), np.stack(cums)
        ends = np.full(8, 599)
        trail_ends(paths, cums, ends, 20 * SPACING, SPACING, 0.25 * SPACING)
    """ % str(Path(__file__).resolve().parent), """
        trail_ends(paths, cums, ends, 20 * SPACING, SPACING, 0.25 * SPACING)
    """, times=100)


def numpy_place_chain(trail, head_arc, offset, spacing, raised=None):
    """body.place_chain in numpy (the code the kernel replaced)."""
    F, S = offset.shape
    offset = np.array(offset, dtype=np.float64, copy=True)
    pos = np.empty((F, S, 3))
    arc = np.empty((F, S))
    w = np.zeros((F, S)) if raised is None or trail.high is None else raised
    rise = (trail.high - trail.points[:, 1]) if trail.high is not None else np.zeros(len(trail.cum))

    def at(s, i):
        q = polyline.sample(trail.points, trail.cum, s)
        wi = w[:, i] if s.ndim == 1 else w[:, i:i + 1]
        oi = offset[:, i] if s.ndim == 1 else offset[:, i:i + 1]
        q[..., 1] += oi + wi * np.interp(s, trail.cum, rise)
        return q

    arc[:, 0] = head_arc
    pos[:, 0] = at(head_arc, 0)
    steps = np.linspace(0.0, 4.0 * spacing, 33)
    rows = np.arange(F)
    for i in range(1, S):
        prev = pos[:, i - 1]
        if raised is not None:
            below = prev[:, 1] - at(arc[:, i - 1], i)[:, 1] - RAISED_RISE * spacing
            offset[:, i] += np.maximum(below, 0.0)
        cand = arc[:, i - 1:i] - steps[None, :]
        beyond = length(at(cand, i) - prev[:, None, :]) > spacing
        k = np.where(beyond.any(axis=1), np.argmax(beyond, axis=1), len(steps) - 1)
        hi = cand[rows, np.maximum(k, 1)]
        lo = cand[rows, np.maximum(k - 1, 0)]
        # a joint whose trail stays within a spacing over all the steps (coiled): the same
        # steps on, up to FARTHER times as far back, never before the trail's start
        j = np.arange(1, (FARTHER - 1) * (len(steps) - 1) + 1)
        far_cand = arc[:, i - 1:i] - (steps[-1] + j[None, :] * (steps[1] - steps[0]))
        far_beyond = ((length(at(far_cand, i) - prev[:, None, :]) > spacing)
                      & (far_cand >= trail.cum[0]))
        far_beyond &= np.cumsum(far_cand < trail.cum[0], axis=1) == 0
        take = ~beyond.any(axis=1) & far_beyond.any(axis=1)
        m = np.argmax(far_beyond, axis=1)
        hi = np.where(take, far_cand[rows, m], hi)
        lo = np.where(take, arc[:, i - 1] - (steps[-1] + m * (steps[1] - steps[0])), lo)
        for _ in range(16):
            mid = 0.5 * (lo + hi)
            far = length(at(mid, i) - prev) > spacing
            hi = np.where(far, mid, hi)
            lo = np.where(far, lo, mid)
        arc[:, i] = 0.5 * (lo + hi)
        pos[:, i] = at(arc[:, i], i)
    return pos, arc


def folding_trail(rng, T: int, high: bool) -> Trail:
    """A trail of T points a fraction of a spacing apart, bumpy, turning, folding back on
    itself at times (a crease, a tight turn) and with repeated points (zero-length segments)."""
    turn = np.cumsum(rng.normal(0.0, 0.2, T))
    turn[rng.random(T) < 0.02] += np.pi
    step = rng.uniform(0.0, 0.3 * SPACING, T) * (rng.random(T) > 0.05)
    xz = np.cumsum(np.stack([np.cos(turn) * step, np.sin(turn) * step], 1), axis=0)
    y = np.cumsum(rng.normal(0.0, 0.002, T)) + 0.01 * (rng.random(T) < 0.01).cumsum()
    pts = np.column_stack([xz[:, 0], y, xz[:, 1]])
    hi = gaussian_filter1d(y, 20.0) + 0.003 if high else None
    return Trail(points=pts, normals=np.tile([0.0, 1.0, 0.0], (T, 1)), ground=y,
                 cum=polyline.arc_lengths(pts), cum_h=polyline.arc_lengths(pts[:, [0, 2]]),
                 high=hi)


@pytest.mark.parametrize("seed", range(8))
def test_place_chain_gives_the_numpy_forms_bits(seed):
    rng = np.random.default_rng(200 + seed)
    T, F, S = int(rng.integers(2, 3000)), int(rng.integers(1, 60)), int(rng.integers(2, 24))
    trail = folding_trail(rng, T, high=bool(seed % 2))
    end = trail.cum[-1]
    head = np.sort(rng.uniform(-0.1 * end - SPACING, 1.1 * end + SPACING, F))
    offset = rng.uniform(0.0, 0.02, (F, S))
    for raised in (None, rng.uniform(0.0, 1.0, (F, S))):
        got = place_chain(trail, head, offset, SPACING, raised=raised)
        want = numpy_place_chain(trail, head, offset, SPACING, raised=raised)
        for g, w in zip(got, want):
            np.testing.assert_array_equal(bits(g), bits(w))


def test_place_chain_of_a_one_point_trail():
    trail = Trail(points=np.array([[0.1, 0.2, 0.3]]), normals=np.array([[0.0, 1.0, 0.0]]),
                  ground=np.array([0.2]), cum=np.zeros(1), cum_h=np.zeros(1),
                  high=np.array([0.25]))
    offset = np.full((3, 4), 0.01)
    for raised in (None, np.full((3, 4), 0.5)):
        got = place_chain(trail, np.array([-1.0, 0.0, 2.0]), offset, SPACING, raised=raised)
        want = numpy_place_chain(trail, np.array([-1.0, 0.0, 2.0]), offset, SPACING, raised)
        for g, w in zip(got, want):
            np.testing.assert_array_equal(bits(g), bits(w))


def test_place_chain_reaches_past_a_coil():
    """A trail coiled tighter than a spacing across for more than the steps' four spacings (a
    cornered head that turned on the spot): every joint still lands exactly a spacing behind
    the one ahead (the steps search on past the coil), as the numpy form does."""
    r = 0.4 * SPACING
    t = np.linspace(0.0, 4.0 * 2.0 * np.pi, 800)             # four loops, ~10 spacings
    coil = np.column_stack([r * np.cos(t) + 3.0 * SPACING, np.zeros_like(t), r * np.sin(t)])
    lead = np.column_stack([np.linspace(-6.0 * SPACING, 3.0 * SPACING + r, 200)[:-1],
                            np.zeros(199), np.zeros(199)])
    pts = np.concatenate([lead, coil])
    trail = Trail(points=pts, normals=np.tile([0.0, 1.0, 0.0], (len(pts), 1)),
                  ground=pts[:, 1], cum=polyline.arc_lengths(pts),
                  cum_h=polyline.arc_lengths(pts[:, [0, 2]]), high=None)
    head = np.array([trail.cum[-1], trail.cum[-1] - 0.3 * SPACING])
    offset = np.zeros((2, 4))
    got = place_chain(trail, head, offset, SPACING)
    want = numpy_place_chain(trail, head, offset, SPACING)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(bits(g), bits(w))
    gaps = length(np.diff(got[0], axis=1))
    np.testing.assert_allclose(gaps, SPACING, rtol=1e-4)
