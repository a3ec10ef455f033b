"""Compiled passes over trails, with the same bits as the numpy and scipy forms they replace
(tests/unit/test_trail_kernels.py compares them):

- `place_chain`: the solve's follow-the-leader placement (body.place_chain), with
  polyline.sample's and np.interp's arithmetic;
- `trail_pass`, `interp_rows`: body.trail_ends (a crowd's body points for the neighbour query,
  placed every few steps of the run for every creature near another): the rows' interpolation
  (np.interp on the shifted arc lengths body._interp_rows makes) and the smoothing
  (scipy.ndimage.gaussian_filter1d's correlation with mode "nearest", after
  straight_ended_smooth's straight ends). trail_pass reads each row's window of the crowd's
  kept paths where it lies (a copy of the windows, held at the head's point after it, gave
  the same bits: a clamped key never reaches a knot after the head), and first_at_or_above
  finds the windows' starts.

- np.interp (numpy/_core/src/multiarray/compiled_base.c, arr_interp): the key's interval j is
  the last with xp[j] <= x; a key on a knot (or on the last one) takes that knot's value, else
  slope * (x - xp[j]) + fp[j] with slope = (fp[j+1] - fp[j]) / (xp[j+1] - xp[j]) (and from the
  other end when that is NaN); a key below the first knot takes fp[0], above the last fp[-1]
  (and with one knot, fp[0]). body._interp_rows shifts each row by its own offset so that the
  rows follow one another in one flat call; a key clipped to its row's range never reaches the
  next row's knots, so the flat call's answer is its row's.
- correlate1d (scipy/ndimage/src/ni_filters.c, NI_Correlate1D) with a symmetric kernel of
  radius r: out = in[0] * w[0], then += (in[-j] + in[j]) * w[j] for j = r down to 1, on the
  line extended by r copies of its end values ("nearest").

The kernels write into arrays they are given and return nothing: they are called directly on
the main thread once compiled (parallel.compiled_call).
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

from baker.parallel import compiled_call


@functools.lru_cache(maxsize=16)
def gaussian_weights(sigma: float) -> np.ndarray:
    """(2 r + 1,) the weights scipy.ndimage.gaussian_filter1d correlates with for `sigma`
    (truncated at 4 sigma), read back from its answer for a unit impulse: each output is
    1 * w[j] plus products with zeros, exactly w[j]. Kept per sigma: not to be written to."""
    from scipy.ndimage import gaussian_filter1d

    r = int(4.0 * float(sigma) + 0.5)
    impulse = np.zeros(2 * r + 1)
    impulse[r] = 1.0
    return gaussian_filter1d(impulse, sigma, mode="constant")


@functools.lru_cache(maxsize=64)
def linspace_to_zero(start: float, count: int) -> np.ndarray:
    """np.linspace(start, 0.0, count), kept per (start, count): trail_ends asks for the same
    few every time it places a crowd's bodies. Not to be written to."""
    out = np.linspace(start, 0.0, count)
    out.flags.writeable = False
    return out


def trail_pass(s, cum, path, rows, starts, ends, stops, base, shift, w_xz, w_y, k, pts,
               arc) -> None:
    """One pass of trail_ends over rows: pts (n, w, 3) = the paths path[rows] (N, T, 3) from
    starts to stops (n,) interpolated at arc lengths s (n, w) on knots cum[rows] less base (n,),
    held at the head's (ends (n,)) after it, and shifted by shift (n,) as body._interp_rows
    does; then x and z smoothed with w_xz after k straight samples at either end, y with w_y;
    arc (n, w) its arc lengths from the first point. The paths are read where they lie (no
    copy of each row's window). pts, arc written (float64, C-contiguous)."""
    compiled_call(_trail_pass, _c(s), _c(cum), _c(path), _i(rows), _i(starts), _i(ends),
                  _i(stops), _c(base), _c(shift), _c(w_xz), _c(w_y), int(k), pts, arc)


def interp_rows(x, xp, fp, shift, out) -> None:
    """out (n, a, d) = np.interp of each row of x (n, a) on knots xp (n, b) with values
    fp (n, b, d), each row shifted by shift (n,) (body._interp_rows); out float64,
    C-contiguous."""
    compiled_call(_interp_rows, _c(x), _c(xp), _c(fp), _c(shift), out)


def _c(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def _i(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.int64)


@njit(cache=True, nogil=True, error_model="numpy")
def _interp_row(x, xp, fp, s, out):
    """np.interp of keys x (a,) on knots xp (b,) + s with values fp (b, d), into out (a, d);
    the keys clipped to the knots' range first, then shifted by s."""
    b = len(xp)
    lo, hi = xp[0], xp[b - 1]
    j = -1
    for i in range(len(x)):
        v = x[i]
        v = lo if v < lo else v                  # np.clip(x, lo, hi)
        v = hi if v > hi else v
        v = v + s
        # the last knot j with xp[j] + s <= v (0 when none): bisected for the first key and
        # a key below the last one's knot, else searched on from the last one (the keys rise);
        # xp + s does not decrease, so either finds the knot a walk from the first would
        if j < 0 or xp[j] + s > v:
            left, right = 0, b
            while left < right:
                mid = (left + right) >> 1
                if xp[mid] + s <= v:
                    left = mid + 1
                else:
                    right = mid
            j = max(left - 1, 0)
        while j + 1 < b and xp[j + 1] + s <= v:
            j += 1
        xj = xp[j] + s
        for c in range(out.shape[1]):
            if j == b - 1 or xj == v:
                out[i, c] = fp[j, c]
            else:
                out[i, c] = _between(v, xj, xp[j + 1] + s, fp[j, c], fp[j + 1, c])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _between(x, x0, x1, y0, y1):
    """np.interp's value at x strictly inside the interval (x0, y0) - (x1, y1): from its
    start, or from its end when that is NaN (and y0 when both are and y0 == y1)."""
    slope = (y1 - y0) / (x1 - x0)
    y = slope * (x - x0) + y0
    if np.isnan(y):
        y = slope * (x - x1) + y1
        if np.isnan(y) and y0 == y1:
            y = y0
    return y


@njit(cache=True, nogil=True, error_model="numpy")
def _interp_rows(x, xp, fp, shift, out):
    for r in range(x.shape[0]):
        _interp_row(x[r], xp[r], fp[r], shift[r], out[r])


@njit(cache=True, nogil=True, error_model="numpy")
def _smooth(line, wts, k, buf, out):
    """gaussian_filter1d(mode="nearest") with weights wts (2 r + 1,) of the line (n,) carried
    on straight for k samples at either end (body.straight_ended_smooth), into out (n,);
    buf: scratch of at least n + 2 k + 2 r."""
    n = len(line)
    r = (len(wts) - 1) // 2
    m = n + 2 * k
    for i in range(k):                     # 2 x[0] - x[k:0:-1]
        buf[r + i] = 2.0 * line[0] - line[k - i]
    for i in range(n):
        buf[r + k + i] = line[i]
    for i in range(k):                     # 2 x[-1] - x[-2:-k-2:-1]
        buf[r + k + n + i] = 2.0 * line[n - 1] - line[n - 2 - i]
    for i in range(r):                     # mode "nearest"
        buf[i] = buf[r]
        buf[r + m + i] = buf[r + m - 1]
    # each output's sum in scipy's order, the offsets outside: the outputs are summed side by
    # side (SIMD) in an array of the kernel's own, which nothing else can alias
    c = r + k
    acc = np.empty(n)
    for i in range(n):
        acc[i] = buf[c + i] * wts[r]
    for d in range(r, 0, -1):
        wd = wts[r - d]
        lo, hi = buf[c - d:c - d + n], buf[c + d:c + d + n]
        for i in range(n):
            acc[i] += (lo[i] + hi[i]) * wd
    out[:] = acc


@njit(cache=True, nogil=True, error_model="numpy")
def _trail_pass(s, cum, path, rows, starts, ends, stops, base, shift, w_xz, w_y, k, pts, arc):
    n, w = s.shape
    raw = np.empty((w, 3))
    line = np.empty(w)
    sm = np.empty(w)
    buf = np.empty(w + 2 * k + len(w_xz) + len(w_y))
    most = 1
    for r in range(n):
        most = max(most, stops[r] - starts[r] + 1)
    xp = np.empty(most)                    # a row's knots, from its first point
    for r in range(n):
        p, a, e, b = rows[r], starts[r], ends[r], stops[r] - starts[r] + 1
        for j in range(b):
            xp[j] = cum[p, min(a + j, e)] - base[r]
        _interp_row(s[r], xp[:b], path[p, a:a + b], shift[r], raw)
        for c in range(3):
            for i in range(w):
                line[i] = raw[i, c]
            if c == 1:
                _smooth(line, w_y, 0, buf, sm)
            else:
                _smooth(line, w_xz, k, buf, sm)
            for i in range(w):
                pts[r, i, c] = sm[i]
        arc[r, 0] = 0.0
        total = 0.0
        for i in range(w - 1):
            d0 = pts[r, i + 1, 0] - pts[r, i, 0]
            d1 = pts[r, i + 1, 1] - pts[r, i, 1]
            d2 = pts[r, i + 1, 2] - pts[r, i, 2]
            seg = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            total = seg if i == 0 else total + seg
            arc[r, i + 1] = total


def place_chain(points, cum, rise, head_arc, offset, w, steps, spacing: float,
                raised_rise: float | None, pos, arc) -> None:
    """body.place_chain's placement, compiled with its arithmetic (the same bits): the head at
    head_arc (F,) on the trail (points (T, 3), cum (T,)), every other joint `spacing` behind
    the joint ahead, found by the first of the arc `steps` back (33,) past it and 16
    bisections; each joint's point raised by offset (F, S) + w (F, S) x the trail's rise
    (T,) over its surface heights there (np.interp on the unclipped arc). raised_rise: None, or
    how far below the joint ahead a joint may start ([m]: offset is raised in place, as
    place_chain does with `raised`). Writes pos (F, S, 3) and arc (F, S)."""
    compiled_call(_place_chain, _c(points), _c(cum), _c(rise), _c(head_arc), offset, _c(w),
                    _c(steps), float(spacing), raised_rise is not None,
                    0.0 if raised_rise is None else float(raised_rise), pos, arc)


@njit(cache=True, nogil=True, error_model="numpy")
def _at_or_below(xp, x):
    """How many of the non-decreasing xp are at or below x (searchsorted "right"), by
    bisection."""
    lo, hi = 0, len(xp)
    while lo < hi:
        mid = (lo + hi) >> 1
        if x >= xp[mid]:
            lo = mid + 1
        else:
            hi = mid
    return lo


def first_at_or_above(cum, rows, ends, values) -> np.ndarray:
    """(n,) int: for each of rows (n,), np.searchsorted(cum[row, :end + 1], value) (side
    "left": how many of the row's arc lengths up to its end (ends (n,)) are below its value
    (values (n,))); cum (N, T) non-decreasing up to each end, no NaN."""
    out = np.empty(len(rows), np.int64)
    compiled_call(_first_at_or_above, _c(cum), _i(rows), _i(ends), _c(values), out)
    return out.astype(np.intp, copy=False)


@njit(cache=True, nogil=True, error_model="numpy")
def _first_at_or_above(cum, rows, ends, values, out):
    for r in range(len(rows)):
        i, x = rows[r], values[r]
        lo, hi = 0, ends[r] + 1
        while lo < hi:
            mid = (lo + hi) >> 1
            if cum[i, mid] < x:
                lo = mid + 1
            else:
                hi = mid
        out[r] = lo


@njit(cache=True, nogil=True, error_model="numpy")
def _interp_one(x, xp, fp):
    """np.interp(x, xp, fp) of one key (arr_interp: left and right values fp[0], fp[-1])."""
    n = len(xp)
    if n == 1:
        return fp[0]                # left, right and the knot's value are all fp[0]
    if x != x:
        return x
    if x > xp[n - 1]:
        return fp[n - 1]
    if x < xp[0]:
        return fp[0]
    j = _at_or_below(xp, x) - 1
    if j == n - 1 or xp[j] == x:
        return fp[j]
    return _between(x, xp[j], xp[j + 1], fp[j], fp[j + 1])


@njit(cache=True, nogil=True, error_model="numpy")
def _at(points, cum, rise, s, off, w, out):
    """polyline.sample(points, cum, s) into out (3,), its y raised by off + w * rise at s
    (place_chain's `at`)."""
    n = len(cum)
    if n == 1:
        out[0], out[1], out[2] = points[0, 0], points[0, 1], points[0, 2]
    else:
        flat = min(max(s, cum[0]), cum[n - 1]) if s == s else s     # np.clip
        # searchsorted(cum, flat, "right") - 1, within the segments (NaN: the last one)
        i = n - 2 if flat != flat else min(max(_at_or_below(cum, flat) - 1, 0), n - 2)
        seg = cum[i + 1] - cum[i]
        t = (flat - cum[i]) / seg if seg > 0 else 0.0
        for c in range(3):
            out[c] = points[i, c] + t * (points[i + 1, c] - points[i, c])
    out[1] += off + w * _interp_one(s, cum, rise)


@njit(cache=True, nogil=True, error_model="numpy")
def _gap(q, px, py, pz):
    """transforms.length(q - p): the sum of squares left to right."""
    d0, d1, d2 = q[0] - px, q[1] - py, q[2] - pz
    return np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


#: how many times the steps' reach _farther searches past them for a point a spacing back
FARTHER = 4


@njit(cache=True, nogil=True, error_model="numpy")
def _farther(points, cum, rise, back, off, w, steps, spacing, px, py, pz, q, hi, lo):
    """(hi, lo): the arcs to bisect between for a joint whose trail, over all of `steps` back
    from the joint ahead, stays within a spacing of it (a body coiled tighter than its steps
    reach: a crowd's cornered head turned on the spot): the same steps on, up to FARTHER times
    as far back, to the first point a spacing away; (hi, lo) as given when there is none (the
    trail's start), so the joint is as close as before."""
    step = steps[1] - steps[0]
    last = steps[len(steps) - 1]
    for j in range(1, (FARTHER - 1) * (len(steps) - 1) + 1):
        s = back - (last + j * step)
        if s < cum[0]:
            break
        _at(points, cum, rise, s, off, w, q)
        if _gap(q, px, py, pz) > spacing:
            return s, back - (last + (j - 1) * step)
    return hi, lo


@njit(cache=True, nogil=True, error_model="numpy")
def _place_chain(points, cum, rise, head_arc, offset, w, steps, spacing, raised, raised_rise,
                 pos, arc):
    F, S = offset.shape
    q = np.empty(3)
    K = len(steps)
    for f in range(F):
        a = head_arc[f]
        arc[f, 0] = a
        _at(points, cum, rise, a, offset[f, 0], w[f, 0], q)
        pos[f, 0, 0], pos[f, 0, 1], pos[f, 0, 2] = q[0], q[1], q[2]
        for i in range(1, S):
            px, py, pz = pos[f, i - 1, 0], pos[f, i - 1, 1], pos[f, i - 1, 2]
            back = arc[f, i - 1]
            if raised:
                _at(points, cum, rise, back, offset[f, i], w[f, i], q)
                below = py - q[1] - raised_rise
                offset[f, i] += below if below >= 0.0 or below != below else 0.0
            k = K - 1
            found = False
            for j in range(K):
                _at(points, cum, rise, back - steps[j], offset[f, i], w[f, i], q)
                if _gap(q, px, py, pz) > spacing:
                    k = j
                    found = True
                    break
            hi = back - steps[max(k, 1)]
            lo = back - steps[max(k - 1, 0)]
            if not found:
                hi, lo = _farther(points, cum, rise, back, offset[f, i], w[f, i], steps,
                                  spacing, px, py, pz, q, hi, lo)
            for _ in range(16):
                mid = 0.5 * (lo + hi)
                _at(points, cum, rise, mid, offset[f, i], w[f, i], q)
                if _gap(q, px, py, pz) > spacing:
                    hi = mid
                else:
                    lo = mid
            a = 0.5 * (lo + hi)
            arc[f, i] = a
            _at(points, cum, rise, a, offset[f, i], w[f, i], q)
            pos[f, i, 0], pos[f, i, 1], pos[f, i, 2] = q[0], q[1], q[2]
