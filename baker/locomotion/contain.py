"""The head's surface test as data, and the head's step with the turns that keep it on the
walkable surface, compiled with numba (HeadSteer.step, _contain, _more_room and the follower's
line of sight), with the other small kernels the run calls every step (layer heights, the
nearest other body point, the agent's largest rise ahead).

A SurfaceTest is `allowed(x, z)` as plain arrays: the navigation grid's columns (the arrays
NavSurface.layer_height reads), the layer's height and tolerance, and, in a crowd, the other
bodies' points near the head, sorted by distance from a reference point (run.follow.Follower
builds it every step). Called, it answers as the Python test it replaces; given to HeadSteer,
the head's whole step runs in the compiled kernels below (head_step), with the same arithmetic
in the same order as head.py's Python (the same bits: tests/unit/test_head_compiled.py).

A turn's look-ahead (_walk) is walked as the agent's paths are: column by column from the head's
base, each column's sample reached by the navigation's link from the one before (a step down
onto a ramp is linked net of the ramp's fall; measured against the head's height, the ramp
beyond lies lower by the step and by its fall as far as the head looks).

These calls are made directly on the main thread, not through parallel.off_main_thread (its
thread hop, 25-95 us, is more than these calls cost, and a 100-creature run makes a hundred
thousand of them). That is safe because each kernel returns only a number or a bool and writes
anything else into arrays it is given: numba converts those in C, while an array returned is
boxed through Python code, where a signal handler's exception (baker.signals) would crash the
process. They are compiled (or loaded from numba's cache) off the main thread first (ready).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, typeof

from baker.navmesh.query import grid_arrays
from baker.navmesh.surface import DIRS
from baker.parallel import off_main_thread

#: points tested along a look-ahead without a grid (HeadSteer.grid None)
LOOK_SAMPLES = 8
#: _contain's result flags: the U-turn's side changed (out[2]); cornered, held still; turned
#: on the spot (the head creeps away from the corner)
SIDE, HELD, CREPT = 1, 2, 4
#: [rad] among other bodies, a head turns at most this far on the spot before it has walked
#: off the corner (2 min_radius): a corner of the trail sharper than a right angle is a cusp
#: the body's chord placement jumps across (metrics.spine_jumps)
SPIN = 0.5 * math.pi
#: no other bodies' points (a SurfaceTest off a crowd)
_NO_NEAR = np.empty((0, 3))
#: the navigation's link direction of a column step (dx + 1, dz + 1) (navmesh.surface.DIRS)
_DIR_OF = np.full((3, 3), -1, dtype=np.int64)
_DIR_OF[DIRS[:, 0] + 1, DIRS[:, 1] + 1] = np.arange(len(DIRS))


#: no slope: the layer's height is compared as it is (SurfaceTest's `slope`)
FLAT = (0.0, 0.0, 0.0, 0.0)


class SurfaceTest:
    """allowed(x, z) -> bool: the column of (x, z) has a walkable sample within `tol` of height
    `y`, or within `tol` and the plane's rise over a cell of the plane through (sx, y, sz)
    rising gx a metre along x and gz along z (`slope`: the head's layer there; a step on a ramp
    is a step net of the ramp's rise over a cell, as the navigation links it between column
    centres: navmesh.build._riser), and the point is at least sqrt(need) from
    every point of `near` that can be that close. near: (k, 3) rows (distance from (rx, rz)
    less a margin, x, z), nearest first: a point farther from (rx, rz) than the test point is
    by more than sqrt(need) is never measured, nor those after it. params: the grid (x0, z0,
    cell, nx, nz), the layer (y, tol), the reference point and reach (rx, rz, sqrt(need),
    need), the slope (sx, sz, gx, gz).
    """

    __slots__ = ("cols", "positions", "normals", "links", "near", "params")

    def __init__(self, nav, y: float, tol: float, near: np.ndarray | None = None,
                 ref: tuple[float, float] = (0.0, 0.0), need: float = 0.0,
                 slope: tuple[float, float, float, float] = FLAT):
        self.cols, self.positions, self.normals, grid = grid_arrays(nav)
        self.links = link_array(nav)
        self.near = _NO_NEAR if near is None else near
        self.params = np.array((*grid.tolist(), y, tol, ref[0], ref[1],
                                math.sqrt(max(need, 0.0)), need, *slope))

    def __call__(self, x: float, z: float) -> bool:
        return _allowed(self.cols, self.positions, self.normals, self.links, self.near, self.params,
                        float(x), float(z))

    def kernel_args(self) -> tuple:
        return self.cols, self.positions, self.normals, self.links, self.near, self.params

    def walk(self, bx: float, bz: float, dx: float, dz: float, s: float, reach: float,
             grid: np.ndarray) -> bool:
        """HeadSteer._contain's free(t, s, reach) along the unit (dx, dz) (_walk; grid: the
        head's, head.grid_array)."""
        return _walk(*self.kernel_args(), float(bx), float(bz), float(dx), float(dz), float(s),
                     float(reach), grid)


def plain_test(nav, y: float, tol: float, near: np.ndarray | None = None,
               ref: tuple[float, float] = (0.0, 0.0), need: float = 0.0,
               slope: tuple[float, float, float, float] = FLAT):
    """SurfaceTest's answers in Python, through nav.layer_height: for any Navigation (a
    SurfaceTest reads a NavSurface's arrays). With `near` points, the test's `bare` is the
    surface's alone (else None). Its `walk` is SurfaceTest.walk where the navigation has a
    grid's arrays and links (None for a test double with only layer_height: each point is then
    tested alone)."""
    root = math.sqrt(max(need, 0.0))
    rows = [] if near is None else near.tolist()
    layer_height = nav.layer_height
    sx, sz, gx, gz = slope
    cell = float(nav.cell_size)

    def clear_of(x: float, z: float) -> bool:
        if rows:
            reach = math.hypot(x - ref[0], z - ref[1]) + root
            for d, px, pz in rows:
                if d > reach:
                    break
                if (px - x) * (px - x) + (pz - z) * (pz - z) < need:
                    return False
        return True

    def allowed(x: float, z: float) -> bool:
        if not clear_of(x, z):
            return False
        h = layer_height(x, y, z, tol)
        if h != h and (gx != 0.0 or gz != 0.0):
            h = layer_height(x, y + gx * (x - sx) + gz * (z - sz), z,
                             tol + math.hypot(gx, gz) * cell)
        return h == h                                 # on the layer: not NaN

    # the surface alone (HeadSteer._contain: turns on the spot among other bodies)
    allowed.bare = plain_test(nav, y, tol, slope=slope) if rows else None
    allowed.walk = _plain_walk(nav, clear_of, y, tol, slope) if hasattr(nav, "col_start") else None
    return allowed


def _plain_walk(nav, clear_of, y: float, tol: float, slope):
    """SurfaceTest.walk for plain_test: the other bodies tested by `clear_of(x, z)` at the
    points SurfaceTest tests them, the columns walked by the compiled _link_walk on the
    navigation's grid arrays and links."""
    cols, pos, nrm, grid = grid_arrays(nav)
    lnk = link_array(nav)
    p = np.array((*grid.tolist(), y, tol, 0.0, 0.0, 0.0, 0.0, *slope))

    def walk(bx: float, bz: float, dx: float, dz: float, s: float, reach: float,
             grid: tuple[float, float, float] | None) -> bool:
        way = way_points(bx, bz, dx, dz, s, reach, grid)
        if not all(clear_of(bx + dx * t, bz + dz * t) for t in (*way[-1:], s, *way[:-1])):
            return False
        return _link_walk(cols, pos, nrm, lnk, p, float(bx), float(bz), float(dx), float(dz),
                          float(s), float(reach if reach > s else s))

    return walk


def way_end(s: float, reach: float, grid: tuple[float, float, float] | None) -> float | None:
    """The last of way_points' distances, without the others (None when there are none)."""
    if reach <= s:
        return None
    return reach if grid is not None else s + (reach - s) * LOOK_SAMPLES / LOOK_SAMPLES


def way_points(x: float, z: float, dx: float, dz: float, s: float, reach: float,
               grid: tuple[float, float, float] | None) -> list[float]:
    """Distances along the unit direction (dx, dz) from (x, z) at which to test the way from
    `s` to `reach` (the point at `s` is tested by the caller): one point inside each grid column
    the way crosses after the first (the middle of its piece there, `reach` in the last), so a
    way that clips a column's corner is seen; without a grid, LOOK_SAMPLES even steps."""
    if reach <= s:
        return []
    if grid is None:
        return [s + (reach - s) * i / LOOK_SAMPLES for i in range(1, LOOK_SAMPLES)] + [
            way_end(s, reach, grid)]
    ts = []
    for o, p, d in ((grid[0], x, dx), (grid[1], z, dz)):
        if d > 1e-12 or d < -1e-12:
            a, b = (p + d * s - o) / grid[2], (p + d * reach - o) / grid[2]
            if a > b:
                a, b = b, a
            ts.extend((o + i * grid[2] - p) / d for i in range(math.floor(a) + 1, math.ceil(b)))
    if not ts:
        return [reach]
    ts.sort()
    return [0.5 * (u + v) for u, v in zip(ts, ts[1:]) if v - u > 1e-12] + [reach]


#: the grids' array types whose kernels are compiled (or loaded) in this process (ready)
_READY: set = set()


def ready(nav) -> None:
    """Compile the kernels for this grid's array types (or load them from numba's cache) on
    parallel.off_main_thread's thread, once per process, before they are called directly: a
    signal whose handler raises during a compile on the main thread lands in LLVM's callbacks,
    which print the exception they ignore."""
    arrays = grid_arrays(nav)
    key = tuple(typeof(a) for a in arrays[:3])
    if key not in _READY:
        off_main_thread(_first_calls, *arrays)
        _READY.add(key)


def _first_calls(cols, pos, nrm, grid) -> None:
    """Every kernel called once on these arrays (ready)."""
    test = SurfaceTest.__new__(SurfaceTest)
    test.cols, test.positions, test.normals = cols, pos, nrm
    test.links = np.full((max(len(pos), 1), 8), -1, dtype=np.int32)
    test.near = np.zeros((1, 3))
    test.params = np.concatenate([grid, (0.0, 1.0, 0.0, 0.0, 0.01, 1e-4), FLAT])
    args = test.kernel_args()
    cos = sin = np.linspace(0.0, 1.0, 3)
    none = np.zeros(3)
    _allowed(*args, 0.0, 0.0)
    more_room(*args, 1.0, 0.0, 0.0, 0.0, 1.0, -1.0, 0.01, cos, sin)
    contain(*args, np.array([1.0, 0.0, 0.0, 0.0, 0.1, 0.2, 1e-3, 4e-3, 0.1, 0.01, 0.04, 1.0,
                             0.0, 3.0, 0.0]), none, cos, sin, cos, sin, np.empty(3))
    line_clear(cols, pos, nrm, grid, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, none)
    head_step(*args, np.zeros(len(ST)), np.linspace(0.1, 1.0, len(PRM)), np.ones(3), none, 0.1,
              1e-3, none, cos, sin, cos, sin)
    layer_height(cols, pos, nrm, grid, 0.0, 0.0, 0.0, 1.0)
    slope_grades(cols, pos, nrm, grid, 0.0, 0.0, 0.1, 0.0, 1.0)
    nearest_sq(np.zeros((1, 2)), 0.0, 0.0)
    largest_jump(np.zeros((2, 3)), 0, 2)


def link_array(nav) -> np.ndarray:
    """The navigation surface's links (navmesh.surface: (N, 8), the sample a step in each
    direction reaches, or -1) as the kernels read them (kept in its query cache, as
    grid_arrays)."""
    cache = nav._cache
    got = cache.get("kernel_links")
    if got is None:
        got = cache["kernel_links"] = np.ascontiguousarray(nav.links, dtype=np.int32)
    return got


@njit(cache=True, nogil=True)
def _split(x):
    """Veltkamp-Dekker: x = hi + lo exactly, hi with half the mantissa."""
    c = 134217729.0 * x
    hi = c - (c - x)
    return hi, x - hi


@njit(cache=True, nogil=True)
def _exact_mul(x, y):
    """(hi, lo): hi = x * y rounded, lo its exact error (Dekker)."""
    xh, xl = _split(x)
    yh, yl = _split(y)
    hi = x * y
    return hi, ((xh * yh - hi) + xh * yl + xl * yh) + xl * yl


@njit(cache=True, nogil=True)
def hypot(a, b):
    """Python's math.hypot(a, b), bit for bit: CPython 3.11's vector_norm (exact squares, a
    compensated sum, a corrected square root). numba's math.hypot is the C library's, which
    rounds differently in about 0.2 % of cases."""
    a, b = abs(a), abs(b)
    if math.isinf(a) or math.isinf(b):
        return math.inf
    if a != a or b != b:
        return math.nan
    top = a if a > b else b
    if top == 0.0:
        return top
    e = math.frexp(top)[1]
    if e < -1023:                   # 2**-e would overflow: CPython 3.11 divides by the largest
        total, frac = 1.0, 0.0
        for x in (a / top, b / top):
            s = total + x * x
            frac += (total - s) + x * x
            total = s
        return top * math.sqrt(total - 1.0 + frac)
    scale = math.ldexp(1.0, -e)
    total, frac1, frac2 = 1.0, 0.0, 0.0
    for x in (a * scale, b * scale):
        hi, lo = _exact_mul(x, x)
        s = total + hi
        frac1 += lo
        frac2 += (total - s) + hi
        total = s
    h = math.sqrt(total - 1.0 + (frac1 + frac2))
    hi, lo = _exact_mul(-h, h)
    s = total + hi
    frac1 += lo
    frac2 += (total - s) + hi
    return (h + (s - 1.0 + (frac1 + frac2)) / (2.0 * h)) / scale


@njit(cache=True, nogil=True)
def largest_jump(points, i0, i1):
    """np.abs(np.diff(points[i0:i1, 1])).max() (PathAgent.largest_rise; NaN when a height is
    NaN)."""
    best = 0.0
    for i in range(i0, i1 - 1):
        d = abs(points[i + 1, 1] - points[i, 1])
        if d != d:
            return math.nan
        if d > best:
            best = d
    return best


@njit(cache=True, nogil=True)
def nearest_sq(points, x, z):
    """((points[:, 0] - x) ** 2 + (points[:, 1] - z) ** 2).min() (the same bits; inf when
    there are no points)."""
    best = math.inf
    for i in range(points.shape[0]):
        dx, dz = points[i, 0] - x, points[i, 1] - z
        d = dx * dx + dz * dz
        if d < best:
            best = d
    return best


@njit(cache=True, nogil=True)
def _cell(p, x, z):
    """The grid cell (ix, iz) of (x, z) (off the grid too)."""
    return math.floor((x - p[0]) / p[2]), math.floor((z - p[1]) / p[2])


@njit(cache=True, nogil=True)
def _column(p, x, z):
    """The grid column of (x, z), -1 off the grid."""
    fx = (x - p[0]) / p[2]
    fz = (z - p[1]) / p[2]
    if not (fx >= 0.0 and fx < p[3] and fz >= 0.0 and fz < p[4]):
        return -1
    return int(fx) * int(p[4]) + int(fz)


@njit(cache=True, nogil=True)
def _height(pos, nrm, k, x, z):
    """The height at (x, z) of walkable sample k's plane."""
    px, py, pz = float(pos[k, 0]), float(pos[k, 1]), float(pos[k, 2])
    return py - (float(nrm[k, 0]) * (x - px) + float(nrm[k, 2]) * (z - pz)) / float(nrm[k, 1])


@njit(cache=True, nogil=True)
def _layer_k(cols, pos, nrm, p, x, y, z, tol):
    """The walkable sample in the column of (x, z) whose plane there is closest to y, -1 when
    none is within tol (navmesh.query.layer_height's choice)."""
    col = _column(p, x, z)
    if col < 0:
        return -1
    best, bestd = -1, tol
    for k in range(cols[col], cols[col + 1]):
        d = abs(_height(pos, nrm, k, x, z) - y)
        if d <= bestd:
            best, bestd = k, d
    return best


@njit(cache=True, nogil=True)
def _layer(cols, pos, nrm, p, x, y, z, tol):
    """navmesh.query.layer_height: the height of the walkable layer in the column of (x, z)
    closest to y, NaN when none is within tol (the same arithmetic)."""
    k = _layer_k(cols, pos, nrm, p, x, y, z, tol)
    return math.nan if k < 0 else _height(pos, nrm, k, x, z)


@njit(cache=True, nogil=True)
def _clear_of(near, p, x, z):
    """(x, z) is at least sqrt(need) from every point of `near` that can be that close."""
    if near.shape[0] > 0:
        reach = hypot(x - p[7], z - p[8]) + p[9]
        for i in range(near.shape[0]):
            if near[i, 0] > reach:
                break
            dx, dz = near[i, 1] - x, near[i, 2] - z
            if dx * dx + dz * dz < p[10]:
                return False
    return True


@njit(cache=True, nogil=True)
def _head_k(cols, pos, nrm, p, x, z):
    """The walkable sample of the head's layer at (x, z) (SurfaceTest's, without the other
    bodies), -1 when there is none."""
    k = _layer_k(cols, pos, nrm, p, x, p[5], z, p[6])
    if k < 0 and (p[13] != 0.0 or p[14] != 0.0):
        k = _layer_k(cols, pos, nrm, p, x, p[5] + p[13] * (x - p[11]) + p[14] * (z - p[12]), z,
                     p[6] + hypot(p[13], p[14]) * p[2])
    return k


@njit(cache=True, nogil=True)
def _allowed(cols, pos, nrm, lnk, near, p, x, z):
    """SurfaceTest's answer for (x, z) (lnk: not read; the surface test's arrays, as every
    kernel takes them)."""
    if not _clear_of(near, p, x, z):
        return False
    return _head_k(cols, pos, nrm, p, x, z) >= 0


@njit(cache=True, nogil=True)
def _walk(cols, pos, nrm, lnk, near, p, bx, bz, dx, dz, s, reach, grid):
    """HeadSteer._contain's free(t, s, reach) along the unit (dx, dz): the step's point at s and
    the way on from it to `reach` (way_points on `grid`) clear of the other bodies (the
    far end first: where a way is blocked, it mostly is there), and every column of the
    navigation's grid from the base (bx, bz) to `reach` on the head's layer, walked by the
    navigation's links from the base's sample (_link_walk)."""
    if near.shape[0] > 0:
        way = np.empty(crossings_bound(s, reach, grid))
        k = way_points_into(bx, bz, dx, dz, s, reach, grid, way)
        if k > 0 and not _clear_of(near, p, bx + dx * way[k - 1], bz + dz * way[k - 1]):
            return False
        if not _clear_of(near, p, bx + dx * s, bz + dz * s):
            return False
        for i in range(k - 1):
            if not _clear_of(near, p, bx + dx * way[i], bz + dz * way[i]):
                return False
    return _link_walk(cols, pos, nrm, lnk, p, bx, bz, dx, dz, s, reach if reach > s else s)


@njit(cache=True, nogil=True)
def _link_walk(cols, pos, nrm, lnk, p, bx, bz, dx, dz, s, reach):
    """Every column from (bx, bz) to `reach` along (dx, dz) holds a sample of the head's layer,
    each reached from the one before by the navigation's link (a step down onto a ramp, linked
    net of the ramp's fall, lies below the head's height by the step and by the ramp's fall as
    far as the way goes), starting at the head's sample at the base; where the base is off the
    head's layer (the slither's edge), at the step's point's."""
    k = _head_k(cols, pos, nrm, p, bx, bz)
    start = 0.0
    if k < 0:
        start = s
        k = _head_k(cols, pos, nrm, p, bx + dx * s, bz + dz * s)
        if k < 0:
            return False
    x, z = bx + dx * start, bz + dz * start
    ix, iz = _cell(p, x, z)
    jx, jz = _cell(p, bx + dx * reach, bz + dz * reach)
    tx, ux, sx = _first_crossing(x, dx, ix, p[0], p[2])
    tz, uz, sz = _first_crossing(z, dz, iz, p[1], p[2])
    # the columns the way crosses, in order (a DDA), each step nearer the last column
    for _ in range(abs(jx - ix) + abs(jz - iz)):
        if ix == jx and iz == jz:
            break
        ex = sx if ix != jx and (iz == jz or tx <= tz) else 0
        ez = sz if iz != jz and (ix == jx or tz <= tx) else 0
        if ex != 0:
            ix, tx = ix + ex, tx + ux
        if ez != 0:
            iz, tz = iz + ez, tz + uz
        k = lnk[k, _DIR_OF[ex + 1, ez + 1]]
        if k < 0:
            return False
    return ix == jx and iz == jz


@njit(cache=True, nogil=True)
def _first_crossing(x, dx, i, o, cell):
    """Along one axis of a way from x with direction dx in cell i of a grid from o: the distance
    to the first cell border, the distance between borders, and the cell step (+1 or -1)."""
    if dx > 0.0:
        return (o + (i + 1) * cell - x) / dx, cell / dx, 1
    if dx < 0.0:
        return (o + i * cell - x) / dx, -cell / dx, -1
    return math.inf, math.inf, 1


@njit(cache=True, nogil=True)
def layer_height(cols, pos, nrm, p, x, y, z, tol):
    """NavSurface.layer_height on grid_arrays' arrays (the same bits)."""
    return _layer(cols, pos, nrm, p, x, y, z, tol)


@njit(cache=True, nogil=True)
def slope_grades(cols, pos, nrm, p, x, z, d, y, tol):
    """(gx, gz) of Follower._slope on grid_arrays' arrays (the same bits): the layer's rise a
    metre along x and z at (x, z), from its heights d either side (follow._grade's one-sided
    rise where one is missing, NaN where both are)."""
    gx = _grade(_layer(cols, pos, nrm, p, x + d, y, z, tol), y,
                _layer(cols, pos, nrm, p, x - d, y, z, tol), d)
    gz = _grade(_layer(cols, pos, nrm, p, x, y, z + d, tol), y,
                _layer(cols, pos, nrm, p, x, y, z - d, tol), d)
    return gx, gz


@njit(cache=True, nogil=True)
def _grade(ahead, here, behind, d):
    """follow._grade compiled: the rise a metre from heights ahead and behind d either side of
    here (one-sided where one is NaN, NaN where both are)."""
    if ahead == ahead and behind == behind:
        return (ahead - behind) / (2.0 * d)
    return (ahead - here) / d if ahead == ahead else (here - behind) / d


@njit(cache=True, nogil=True)
def circle_room(cols, pos, nrm, lnk, near, p, hx, hz, px, pz, side, r, beat, cos, sin):
    """HeadSteer._circle_room: how many points round the first half of the circle of radius r
    on `side` the head reaches walking it from (px, pz), heading (hx, hz); beat < 0: no beat."""
    steps = cos.shape[0] - 1
    lx, lz = side * hz, -side * hx
    cx, cz = px + r * lx, pz + r * lz
    d = math.pi * r / steps
    n = 0
    for j in range(steps):
        if beat >= 0 and (n > beat or n + steps - j <= beat):
            break
        c, s = cos[j + 1], sin[j + 1]
        qx, qz = cx + r * (-lx * c + hx * s), cz + r * (-lz * c + hz * s)
        m = max(1, math.ceil(hypot(qx - px, qz - pz) / d - 1e-9))
        reached = True
        for i in range(1, m + 1):
            if not _allowed(cols, pos, nrm, lnk, near, p, px + (qx - px) * i / m,
                            pz + (qz - pz) * i / m):
                reached = False
                break
        if reached:
            n += 1
            px, pz = qx, qz
    return n


@njit(cache=True, nogil=True)
def more_room(cols, pos, nrm, lnk, near, p, hx, hz, px, pz, first, second, r, cos, sin):
    """HeadSteer._more_room: more points reached round the circle on `second` than on
    `first`."""
    room = circle_room(cols, pos, nrm, lnk, near, p, hx, hz, px, pz, first, r, -1, cos, sin)
    return circle_room(cols, pos, nrm, lnk, near, p, hx, hz, px, pz, second, r, room, cos,
                       sin) > room


@njit(cache=True, nogil=True)
def _crossings(x, dx, s, reach, o, cell, ts, n):
    """head.way_points' column crossings along one axis, appended to ts[n:]; returns the new
    count."""
    if dx > 1e-12 or dx < -1e-12:
        a, b = (x + dx * s - o) / cell, (x + dx * reach - o) / cell
        if a > b:
            a, b = b, a
        for i in range(math.floor(a) + 1, math.ceil(b)):
            ts[n] = (o + i * cell - x) / dx
            n += 1
    return n


@njit(cache=True, nogil=True)
def way_points_into(x, z, dx, dz, s, reach, grid, out):
    """way_points into out (grid: (x0, z0, cell), or a cell <= 0 for none); returns how
    many. out must hold the way's column crossings plus one (crossings_bound)."""
    if reach <= s:
        return 0
    if grid[2] <= 0.0:
        for i in range(1, LOOK_SAMPLES):
            out[i - 1] = s + (reach - s) * i / LOOK_SAMPLES
        out[LOOK_SAMPLES - 1] = s + (reach - s) * LOOK_SAMPLES / LOOK_SAMPLES
        return LOOK_SAMPLES
    ts = np.empty(out.shape[0])
    n = _crossings(x, dx, s, reach, grid[0], grid[2], ts, 0)
    n = _crossings(z, dz, s, reach, grid[1], grid[2], ts, n)
    if n == 0:
        out[0] = reach
        return 1
    for i in range(1, n):          # insertion sort: a few crossings (the same order as a sort)
        v, j = ts[i], i - 1
        while j >= 0 and ts[j] > v:
            ts[j + 1] = ts[j]
            j -= 1
        ts[j + 1] = v
    k = 0
    for i in range(n - 1):
        if ts[i + 1] - ts[i] > 1e-12:
            out[k] = 0.5 * (ts[i] + ts[i + 1])
            k += 1
    out[k] = reach
    return k + 1


@njit(cache=True, nogil=True)
def crossings_bound(s, reach, grid):
    """At least the length way_points needs for a way from s to reach."""
    if grid[2] <= 0.0:
        return LOOK_SAMPLES
    return int(2.0 * (abs(reach - s) / grid[2] + 2.0)) + 1


@njit(cache=True, nogil=True)
def _free(cols, pos, nrm, lnk, near, p, hx, hz, bx, bz, t, s, reach, grid):
    """HeadSteer._contain's free(t, s, reach): the step of length s turned by t, and the
    straight way on from it to `reach`, on the surface (_walk)."""
    c, sn = math.cos(t), math.sin(t)
    return _walk(cols, pos, nrm, lnk, near, p, bx, bz, c * hx + sn * hz, -sn * hx + c * hz, s,
                 reach, grid)


@njit(cache=True, nogil=True)
def _clamp(x, lo, hi):
    """Python's max(lo, min(hi, x)), ties and signed zeros included."""
    y = x if x < hi else hi
    return y if y > lo else lo


@njit(cache=True, nogil=True)
def contain(cols, pos, nrm, lnk, near, p, h, grid, cos, sin, fracs, deflect, out):
    """HeadSteer._contain. h: (hx, hz, bx, bz, a, ang, step, dt, tight_speed, min_radius,
    turn_radius, u_side, hold, max_yaw_rate, spun: the turn on the spot since the head last
    walked off a corner). Writes (a, step, u_side) to out and returns the flags (SIDE, HELD,
    CREPT) of what else changed."""
    hx, hz, bx, bz, a, ang, step, dt = h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7]
    min_radius, turn_radius = h[9], h[10]
    side = 1.0 if ang >= a else -1.0
    slow = h[8] * dt
    slow = slow if slow < step else step
    tight = slow / min_radius
    reach = 0.25 * turn_radius
    reach = 2.0 * min_radius if 2.0 * min_radius > reach else reach
    reach = step if step > reach else reach
    out[0], out[1], out[2] = a, step, h[11]
    if _free(cols, pos, nrm, lnk, near, p, hx, hz, bx, bz, a, step, reach, grid):
        return 0
    tighter = np.empty(2 * fracs.shape[0])
    for i in range(fracs.shape[0]):
        tighter[2 * i] = _clamp(a + side * fracs[i] * tight, -tight, tight)
        tighter[2 * i + 1] = _clamp(a + -side * fracs[i] * tight, -tight, tight)
    for t in tighter:
        if _free(cols, pos, nrm, lnk, near, p, hx, hz, bx, bz, t, slow, reach, grid):
            out[0], out[1] = t, slow
            return 0
    clear0 = _free(cols, pos, nrm, lnk, near, p, hx, hz, bx, bz, side * tight, slow, slow, grid)
    clear1 = _free(cols, pos, nrm, lnk, near, p, hx, hz, bx, bz, -side * tight, slow, slow, grid)
    if clear0 or clear1:
        k = more_room(cols, pos, nrm, lnk, near, p, hx, hz, bx, bz, side, -side, min_radius, cos,
                      sin)
        if (clear1 if k else clear0):
            sd = -side if k else side
            out[0], out[1] = sd * tight, slow
            if h[11] != 0.0:
                out[2] = sd
                return SIDE
            return 0
    if _free(cols, pos, nrm, lnk, near, p, hx, hz, bx, bz, a, step, step, grid):
        return 0
    for t in tighter:
        if _free(cols, pos, nrm, lnk, near, p, hx, hz, bx, bz, t, slow, slow, grid):
            out[0], out[1] = t, slow
            return 0
    if h[12] != 0.0:
        out[0], out[1] = 0.0, 0.0
        return HELD
    turn = h[13] * dt
    want = ang
    found = False
    for d in deflect:
        for sd in (side, -side):
            t = a + sd * d
            if _free(cols, pos, nrm, lnk, near, p, hx, hz, bx, bz, t, step, step, grid):
                want, found = t, True
                break
        if found:
            break
    t = _clamp(want, -turn, turn)
    # among other bodies, no more than SPIN in turns on the spot before the head has walked
    # off (held instead), where the surface alone would let it walk toward the agent
    if near.shape[0] > 0 and h[14] + abs(t) > SPIN:
        if _free(cols, pos, nrm, lnk, near[:0], p, hx, hz, bx, bz, ang, step, step, grid):
            out[0], out[1] = 0.0, 0.0
            return HELD
    out[0], out[1] = t, 0.0
    return CREPT


#: HeadSteer's state in head_step's `st` (read and written) and its settings in `prm`
ST = ("bx", "by", "bz", "hx", "hz", "phase", "lateral_amp", "sx", "sz", "u_side", "creep",
      "hold", "held", "speed", "px", "py", "pz", "spun")
PRM = ("lead", "max_speed", "speed_cap", "tight_speed", "turn_radius", "max_yaw_rate",
       "min_radius", "turn_rate", "turn_rate_scale", "amplitude", "max_offset", "catch_up")


@njit(cache=True, nogil=True)
def _wave(st, prm, u, hx, hz, bx, by, bz, dt):
    """The end of head_step: the head's side-to-side wave at speed u (phase st[5], amplitude
    st[6], smoothed heading st[7:9]) and the waved head point st[14:17]."""
    max_speed, turn_radius = prm[1], prm[4]
    frac = u / max_speed
    frac = frac if frac < 2.0 else 2.0
    rate = prm[7] * prm[8]
    omega = rate * frac
    st[5] += omega * dt
    if omega > 1e-9:
        want = u * prm[9] / (rate if rate > 1e-9 else 1e-9)
        want = prm[10] if prm[10] < want else want
    else:
        want = st[6]
    dmax = 0.1 * u * dt
    st[6] += _clamp(want - st[6], -dmax, dmax)
    w = u * dt / (0.5 * turn_radius)
    w = w if w < 1.0 else 1.0
    sx, sz = st[7], st[8]
    dx, dz = sx + w * (hx - sx), sz + w * (hz - sz)
    n = hypot(dx, dz)
    if n > 1e-9:
        sx, sz = dx / n, dz / n
        st[7], st[8] = sx, sz
    k = st[6] * math.sin(st[5])
    st[14], st[15], st[16] = bx + sz * k, by + 0.0 * k, bz + -sx * k


@njit(cache=True, nogil=True)
def head_step(cols, pos, nrm, lnk, near, p, st, prm, agent, aim, agent_speed, dt, grid, cos, sin,
              fracs, deflect):
    """HeadSteer.step with a SurfaceTest, the same arithmetic in the same order: st (ST) is
    updated in place; agent (3,), aim (3,) or NaN (none). Returns 1 when the base moved (the
    heading and base are new), else 0."""
    bx, by, bz, hx, hz = st[0], st[1], st[2], st[3], st[4]
    lead, max_speed, speed_cap, turn_radius = prm[0], prm[1], prm[2], prm[4]
    ax, ay, az = agent[0], agent[1], agent[2]
    tx, tz = ax - bx, az - bz
    dist = hypot(tx, tz)
    if aim[0] == aim[0] and hypot(aim[0] - bx, aim[2] - bz) > 1e-9:
        tx, tz = aim[0] - bx, aim[2] - bz
        dist = hypot(tx, tz) + hypot(ax - aim[0], az - aim[2])
    u = agent_speed + 4.0 * (dist - lead)          # Python's min(u, catch-up, cap), max(0, ..)
    cap = prm[11] * max_speed
    u = cap if cap < u else u
    u = speed_cap if speed_cap < u else u
    u = u if u > 0.0 else 0.0
    if dist < 1e-9:
        u = 0.0
    moved = 0
    if u > 0.0 and dist > 1e-9:
        if agent_speed == 0.0:
            rest = dist - 0.25 * lead
            rest = 0.0 if 0.0 > rest else rest
            step = u * dt
            step = rest if rest < step else step
        else:
            step = u * dt
        if st[10] > 0.0:
            slow = prm[3] * dt
            step = slow if slow < step else step
        m = hypot(tx, tz)
        m = 1e-12 if 1e-12 > m else m
        wx, wz = tx / m, tz / m
        ang = math.atan2(hz * wx - hx * wz, hx * wx + hz * wz)
        if abs(ang) <= 0.5 * math.pi:                  # HeadSteer._u_turn
            st[9] = 0.0
        else:
            if st[9] == 0.0:
                side = 1.0 if ang >= 0.0 else -1.0
                if more_room(cols, pos, nrm, lnk, near, p, hx, hz, bx, bz, side, -side, turn_radius,
                             cos, sin):
                    side = -side
                st[9] = side
            if ang * st[9] < 0.0:
                ang += st[9] * 2.0 * math.pi
        lim = step / turn_radius
        if abs(ang) > 0.5:
            quick = prm[5] * turn_radius * dt
            step = quick if quick < step else step
            lim = step / turn_radius
        a = _clamp(ang, -lim, lim)
        if _allowed(cols, pos, nrm, lnk, near, p, bx, bz):
            h = np.array([hx, hz, bx, bz, a, ang, step, dt, prm[3], prm[6], turn_radius, st[9],
                          st[11], prm[5], st[17]])
            out = np.empty(3)
            flags = contain(cols, pos, nrm, lnk, near, p, h, grid, cos, sin, fracs, deflect, out)
            a, step = out[0], out[1]
            if flags & SIDE:
                st[9] = out[2]
            if flags & HELD:
                st[12] = 1.0
            if flags & CREPT:
                st[10] = 2.0 * prm[6]
                st[17] += abs(a)
        creep = st[10] - step
        st[10] = creep if creep > 0.0 else 0.0
        if st[10] == 0.0:
            st[17] = 0.0
        c, sn = math.cos(a), math.sin(a)
        hx, hz = c * hx + sn * hz, -sn * hx + c * hz
        bx, by, bz = bx + hx * step, ay, bz + hz * step
        st[0], st[1], st[2], st[3], st[4] = bx, by, bz, hx, hz
        u = step / dt
        moved = 1
    st[13] = u
    _wave(st, prm, u, hx, hz, bx, by, bz, dt)
    return moved


@njit(cache=True, nogil=True)
def line_clear(cols, pos, nrm, p, bx, bz, dx, dz, n, y, tol, grid):
    """Follower._clear's walk: the straight line from (bx, bz) along (dx, dz) (n long) stays on
    the layer, continued from height y point by point (head.way_points' points)."""
    way = np.empty(crossings_bound(0.0, n, grid))
    k = way_points_into(bx, bz, dx / n, dz / n, 0.0, n, grid, way)
    for i in range(k):
        r = way[i]
        y = _layer(cols, pos, nrm, p, bx + r * dx / n, y, bz + r * dz / n, tol)
        if y != y:
            return False
    return True
