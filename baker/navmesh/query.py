"""Queries on a built surface (Detour's side): nearest point, random reachable point, path.

NavSurface is the query object over one NavData (surface.py, the plain arrays the build makes and
the cache stores), as Detour's dtNavMeshQuery is over a dtNavMesh; it satisfies the Navigation
protocol (protocol.py). All functions here take a NavSurface first; its methods call them.
Expected failures (nothing near, unreachable goal) are results (None, complete=False), never
exceptions. Heavier lookup structures (KD-tree, coarse-graph arrays) are built lazily on first use
and kept in the NavSurface's private cache, never in the data.
"""

from __future__ import annotations

import heapq
import math

import numpy as np

from baker.navmesh.surface import DIRS, NavData, PathResult

#: Ring radius (in columns) searched on the grid before falling back to the KD-tree.
_RING = 3
#: (dx + 1, dz + 1) -> direction index into DIRS.
_DIR_OF = np.full((3, 3), -1, dtype=np.int64)
for _d, (_dx, _dz) in enumerate(DIRS):
    _DIR_OF[_dx + 1, _dz + 1] = _d


class NavSurface:
    """Queries over a NavData (the query object; the data stays plain arrays).

    The data's fields (positions, links, cell_size, ...) are attributes of the query object
    too (the same arrays, not copies), so code reads `nav.positions` whichever it holds.
    Pickles as its data (the lazy tables are rebuilt on use).
    """

    def __init__(self, data: NavData):
        self.data = data
        self.__dict__.update(data.arrays())
        self._cache: dict = {}

    def __getstate__(self):
        return {"data": self.data}

    def __setstate__(self, state):
        self.__init__(state["data"])

    # ------------------------------------------------------------------ plain properties
    @property
    def n_samples(self) -> int:
        return self.data.n_samples

    @property
    def n_components(self) -> int:
        return self.data.n_components

    @property
    def walkable_area(self) -> float:
        """Horizontal walkable area, m^2 (samples x cell^2)."""
        return self.data.walkable_area

    def stats(self) -> dict:
        """Summary for reports (plain JSON types)."""
        return self.data.stats()

    def arrays(self) -> dict:
        """Every field of the data as a dict of numpy arrays / scalars."""
        return self.data.arrays()

    @property
    def link_indptr(self) -> np.ndarray:
        """CSR view of the links: (N + 1,) int64 (see link_indices)."""
        return _link_csr(self)[0]

    @property
    def link_indices(self) -> np.ndarray:
        """CSR view of the links: (L,) int32 neighbour samples, rows in sample order."""
        return _link_csr(self)[1]

    def prepare(self) -> "NavSurface":
        """Build the lazy query tables now (coarse-graph arrays, members, block index) instead
        of on the first query (about 0.1-0.3 s on a few million samples). Returns self."""
        _coarse_arrays(self)
        _members(self)
        _coarse_index(self)
        return self

    # ------------------------------------------------------------------ queries (Navigation)
    def nearest(self, p, max_dist: float = np.inf) -> np.ndarray | None:
        """(3,) closest walkable surface point to p (within max_dist, 3D), or None."""
        return nearest(self, p, max_dist)

    def random_point_near(self, p, radius: float, rng: np.random.Generator) -> np.ndarray | None:
        """(3,) random walkable point within `radius` (3D) of p, reachable from p, uniform by
        surface area; None when there is none."""
        return random_point_near(self, p, radius, rng)

    def find_path(self, a, b) -> PathResult:
        """Shortest-ish smoothed path from a to b on the surface (see find_path)."""
        return find_path(self, a, b)

    def is_walkable(self, points, tol: float | None = None) -> np.ndarray:
        """(n,) bool: points within `tol` (vertically) of the walkable surface."""
        return is_walkable(self, points, tol)

    def component_of(self, p) -> int:
        """Component label of the sample nearest p, -1 when the surface is empty."""
        return component_of(self, p)

    def surface_height(self, points, tol: float = np.inf) -> np.ndarray:
        """(n,) surface height under each point (the layer closest in height), NaN if none."""
        return surface_height(self, points, tol)

    def layer_height(self, x: float, y: float, z: float, tol: float) -> float:
        """Height of the walkable layer in the column of (x, z) closest to y (within tol, else
        NaN): a scalar surface_height for per-step use."""
        return layer_height(self, x, y, z, tol)

    def resample_path(self, points, spacing: float | None = None) -> np.ndarray:
        """(m, 3) points along a path every `spacing` m, heights on the walked surface."""
        return resample_path(self, points, spacing)

    def segment_visible(self, a, b) -> bool:
        """True when the straight segment a-b stays on linked walkable samples of one layer."""
        return segment_visible(self, a, b)



# --------------------------------------------------------------------------- helpers
def _pt(p) -> np.ndarray:
    return np.asarray(p, dtype=np.float64).reshape(3)


def _columns(s: NavSurface, x, z):
    """Column indices (ix, iz) of world x, z (arrays); may be out of the grid."""
    c = s.cell_size
    ix = np.floor((np.asarray(x, np.float64) - s.origin[0]) / c).astype(np.int64)
    iz = np.floor((np.asarray(z, np.float64) - s.origin[1]) / c).astype(np.int64)
    return ix, iz


def _plane_y(s: NavSurface, idx, x, z):
    """Height of the tangent plane of samples idx at (x, z)."""
    p = s.positions[idx].astype(np.float64)
    n = s.normals[idx].astype(np.float64)
    return p[..., 1] - (n[..., 0] * (x - p[..., 0]) + n[..., 2] * (z - p[..., 2])) / n[..., 1]


def _window(s: NavSurface, ix0, ix1, iz0, iz1) -> np.ndarray:
    """Sample indices in the column rectangle [ix0, ix1] x [iz0, iz1] (clipped to the grid)."""
    nx, nz = s.shape
    ix0, iz0 = max(int(ix0), 0), max(int(iz0), 0)
    ix1, iz1 = min(int(ix1), nx - 1), min(int(iz1), nz - 1)
    if ix0 > ix1 or iz0 > iz1:
        return np.zeros(0, dtype=np.int64)
    rows = np.arange(ix0, ix1 + 1, dtype=np.int64) * nz
    a = s.col_start[rows + iz0]
    b = s.col_start[rows + iz1 + 1]
    ln = b - a
    tot = int(ln.sum())
    if tot == 0:
        return np.zeros(0, dtype=np.int64)
    off = np.repeat(a - np.concatenate([[0], np.cumsum(ln)[:-1]]), ln)
    return off + np.arange(tot, dtype=np.int64)


def _rep_kdtree(s: NavSurface):
    """KD-tree over the coarse representatives (far fewer points than samples), and the
    largest distance from a representative to a member of its node."""
    t = s._cache.get("rep_kdtree")
    if t is None:
        from scipy.spatial import cKDTree

        ext = _coarse_index(s)[3]
        t = (cKDTree(s.positions[s.coarse_rep]), float(ext.max()) if len(ext) else 0.0)
        s._cache["rep_kdtree"] = t
    return t


def _snap(s: NavSurface, idx: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(k, 3) surface points of samples idx closest to p: p's (x, z) on the sample's plane
    when p is inside the sample's column, else the sample's centre."""
    out = s.positions[idx].astype(np.float64)
    ix, iz = _columns(s, p[0], p[2])
    inside = (s.cells[idx, 0] == ix) & (s.cells[idx, 1] == iz)
    if inside.any():
        j = idx[inside]
        out[inside, 0] = p[0]
        out[inside, 2] = p[2]
        out[inside, 1] = _plane_y(s, j, p[0], p[2])
    return out


def _best_in(s: NavSurface, idx: np.ndarray, p: np.ndarray):
    if len(idx) == 0:
        return -1, None, np.inf
    q = _snap(s, idx, p)
    d = np.linalg.norm(q - p, axis=1)
    k = int(np.argmin(d))
    return int(idx[k]), q[k], float(d[k])


def _nearest_sample(s: NavSurface, p: np.ndarray, max_dist: float = np.inf):
    """(sample index, surface point) closest to p within max_dist, or (-1, None).

    Grid windows of growing size around p's column (exact once the best distance is within
    the window), then a KD-tree over the coarse representatives for far-away points."""
    if s.n_samples == 0:
        return -1, None
    c = s.cell_size
    ix, iz = _columns(s, p[0], p[2])
    best, bp, bd = -1, None, np.inf
    for r in (_RING, 16, 64):
        if math.isfinite(max_dist):
            r = min(r, int(math.ceil(max_dist / c)))
        best, bp, bd = _best_in(s, _window(s, ix - r, ix + r, iz - r, iz + r), p)
        if best >= 0 and bd > (r + 0.5) * c and math.ceil(bd / c) <= 64:
            r = int(math.ceil(bd / c))  # one window that surely holds the nearest sample
            best, bp, bd = _best_in(s, _window(s, ix - r, ix + r, iz - r, iz + r), p)
        if best >= 0 and bd <= (r + 0.5) * c:
            break
        if (r + 0.5) * c >= max_dist:
            break
    else:
        tree, ext = _rep_kdtree(s)
        dr, _ = tree.query(p, k=1)
        if math.isfinite(dr) and dr - ext <= min(bd, max_dist):
            nodes = tree.query_ball_point(p, dr + 2.0 * ext)
            order, indptr = _members(s)
            idx = np.concatenate([order[indptr[u]:indptr[u + 1]] for u in nodes])
            k2, q2, d2 = _best_in(s, idx, p)
            if d2 < bd:
                best, bp, bd = k2, q2, d2
    if best < 0 or bd > max_dist:
        return -1, None
    return best, bp


def _link_csr(s: NavSurface):
    """CSR view of the links (indptr (N + 1,) int64, indices (L,) int32), built once."""
    c = s._cache.get("csr")
    if c is None:
        m = s.links >= 0
        indptr = np.zeros(len(s.links) + 1, dtype=np.int64)
        np.cumsum(m.sum(axis=1), out=indptr[1:])
        c = (indptr, s.links[m].astype(np.int32))
        s._cache["csr"] = c
    return c


def _members(s: NavSurface):
    """CSR coarse node -> samples (order, indptr)."""
    m = s._cache.get("members")
    if m is None:
        order = np.argsort(s.coarse_of, kind="stable")
        indptr = np.zeros(len(s.coarse_rep) + 1, dtype=np.int64)
        np.cumsum(np.bincount(s.coarse_of, minlength=len(s.coarse_rep)), out=indptr[1:])
        m = (order, indptr)
        s._cache["members"] = m
    return m


def _coarse_lists(s: NavSurface):
    """The coarse graph as plain lists for A*: CSR indptr and indices, the representatives'
    (x, y, z), and per node its [(neighbour, edge length), ...] once A* has expanded it (None
    before: searches from nearby starts expand the same nodes)."""
    c = s._cache.get("coarse_lists")
    if c is None:
        c = (s.coarse_indptr.tolist(), s.coarse_indices.tolist(),
             s.positions[s.coarse_rep].astype(np.float64).tolist(), [None] * len(s.coarse_rep))
        s._cache["coarse_lists"] = c
    return c


# --------------------------------------------------------------------------- public queries
def nearest(s: NavSurface, p, max_dist: float = np.inf) -> np.ndarray | None:
    """The walkable surface point closest to p (3D), like Unity's NavMesh.SamplePosition.

    p : (3,) world. Returns (3,) float64, or None when nothing is within max_dist."""
    _, q = _nearest_sample(s, _pt(p), max_dist)
    return None if q is None else q.copy()


def component_of(s: NavSurface, p) -> int:
    """Component label of the surface near p (the nearest sample), -1 when the surface is empty."""
    k, _ = _nearest_sample(s, _pt(p))
    return -1 if k < 0 else int(s.component[k])


def _locate(s: NavSurface, points: np.ndarray, tol: float):
    """Per point: the sample of its column whose plane height is closest (the first of
    equals), and that height; (-1, NaN) when none is within tol vertically. A point on a cell
    border (path corners often are) found in no column tries the neighbouring columns, each
    point taking the first of _NUDGES to find one. Compiled (navmesh.locate): the same bits as
    _locate_few's Python."""
    from baker.navmesh.locate import locate

    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    if len(pts) == 0 or s.n_samples == 0:
        return np.full(len(pts), -1, dtype=np.int64), np.full(len(pts), np.nan)
    return locate(*grid_arrays(s), pts, tol, True, _NUDGE_ARRAY)


def grid_arrays(s) -> tuple:
    """(col_start, positions, normals, [x0, z0, cell, nx, nz]) of the navigation surface's
    current grid, as the compiled kernels read them (navmesh.locate, locomotion.contain), kept
    in its query cache (a lazy surface's grid is that of its current window)."""
    cache = s._cache
    got = cache.get("kernel_grid")
    if got is None:
        got = cache["kernel_grid"] = (
            np.ascontiguousarray(np.asarray(s.col_start)),
            np.ascontiguousarray(np.asarray(s.positions)),
            np.ascontiguousarray(np.asarray(s.normals)),
            np.array([s.origin[0], s.origin[1], s.cell_size, s.shape[0], s.shape[1]],
                     dtype=np.float64))
    return got


#: _walk remembers up to this many walks per surface (then starts afresh)
_WALKS_KEPT = 1 << 16
#: _coarse_candidates remembers up to this many (point, radius) draws per surface, those
#: asked for twice (of the last _SEEN_KEPT asked for)
_CANDIDATES_KEPT = 64
_SEEN_KEPT = 4096
#: _member_weights remembers up to this many coarse nodes' weights per surface
_MEMBERS_KEPT = 4096


def _kept(s: NavSurface, name: str, limit: int, kind):
    """The surface's remembered table `name` (a dict or set, `kind`), started afresh when it
    holds `limit` entries (per-query memories: their keys never repeat for some callers)."""
    table = s._cache.get(name)
    if table is None or len(table) >= limit:
        table = s._cache[name] = kind()
    return table
#: the nudges _locate tries, in order, for a point on a cell border (times 1e-6 cells)
_NUDGES = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0), (1.0, 1.0), (-1.0, -1.0),
           (1.0, -1.0), (-1.0, 1.0))
_NUDGE_ARRAY = np.array(_NUDGES)


def _locate_few(s: NavSurface, pts: np.ndarray, tol: float, retry: bool = True):
    """_locate in Python floats, one point at a time: the reference the compiled _locate is
    tested against (the same samples tried in the same order with _plane_y's arithmetic)."""
    best, besth = [], []
    eps = 1e-6 * s.cell_size
    for x, y, z in pts.tolist():
        k, h = _locate_one(s, x, y, z, tol)
        if k < 0 and retry:
            for ex, ez in _NUDGES:
                k, h = _locate_one(s, x + ex * eps, y + 0.0, z + ez * eps, tol)
                if k >= 0:
                    break
        best.append(k)
        besth.append(h)
    return np.array(best, dtype=np.int64), np.array(besth, dtype=np.float64)


def _locate_one(s: NavSurface, x: float, y: float, z: float, tol: float) -> tuple[int, float]:
    """(sample, plane height) of the sample in the column of (x, z) whose plane height is
    closest to y (the first of equals), or (-1, NaN) when none is within tol."""
    c = s.cell_size
    if not (math.isfinite(x) and math.isfinite(z)):
        return -1, math.nan
    ix = math.floor((x - s.origin[0]) / c)
    iz = math.floor((z - s.origin[1]) / c)
    nx, nz = s.shape
    if not (0 <= ix < nx and 0 <= iz < nz):
        return -1, math.nan
    col = ix * nz + iz
    best, besth, bestd = -1, math.nan, math.inf
    for k, (px, py, pz, nxk, nyk, nzk) in enumerate(_column_planes(s, col)):
        h = py - (nxk * (x - px) + nzk * (z - pz)) / nyk
        d = abs(h - y)
        if d < bestd and d <= tol:
            best, besth, bestd = k, h, d
    if best >= 0:
        best += int(s.col_start[col])
    return best, besth


def layer_height(s: NavSurface, x: float, y: float, z: float, tol: float) -> float:
    """Scalar surface_height for one point (the per-step fast path of the simulation loop):
    the height of the walkable layer in the column of (x, z) closest to y, NaN if none is
    within tol. Unlike _locate it does not retry neighbouring columns on cell borders."""
    c = s.cell_size
    ix = math.floor((x - s.origin[0]) / c)
    iz = math.floor((z - s.origin[1]) / c)
    nx, nz = s.shape
    if not (0 <= ix < nx and 0 <= iz < nz):
        return math.nan
    col = ix * nz + iz
    planes = s._cache.get("column_planes", _NO_COLUMNS).get(col)     # _column_planes, inline
    if planes is None:
        planes = _column_planes(s, col)
    best, bestd = math.nan, tol
    for px, py, pz, nxk, nyk, nzk in planes:
        h = py - (nxk * (x - px) + nzk * (z - pz)) / nyk
        d = abs(h - y)
        if d <= bestd:
            best, bestd = h, d
    return best


#: no column read yet (layer_height's look-up before _column_planes makes the table)
_NO_COLUMNS: dict = {}


def _column_planes(s: NavSurface, col: int) -> list:
    """[(x, y, z, nx, ny, nz), ...] the position and normal of each sample of column `col`, top
    to bottom, as Python floats (each column read from the arrays once per surface:
    layer_height runs every step)."""
    cols = s._cache.get("column_planes")
    if cols is None:
        cols = s._cache["column_planes"] = {}
    planes = cols.get(col)
    if planes is None:
        a, b = int(s.col_start[col]), int(s.col_start[col + 1])
        planes = cols[col] = [(*p, *n) for p, n in zip(s.positions[a:b].tolist(),
                                                       s.normals[a:b].tolist())]
    return planes


def _default_tol(s: NavSurface) -> float:
    return max(0.5 * s.step_height, 1e-3 * s.cell_size, 1e-6)


def is_walkable(s: NavSurface, points, tol: float | None = None) -> np.ndarray:
    """(n,) bool: each point lies within `tol` metres (vertically) of a walkable sample's
    surface in its column. Default tol: half the step height."""
    tol = _default_tol(s) if tol is None else float(tol)
    return _locate(s, points, tol)[0] >= 0


def surface_height(s: NavSurface, points, tol: float = np.inf) -> np.ndarray:
    """(n,) height of the walkable layer closest (vertically) to each point, NaN if none
    within tol or off the surface."""
    return _locate(s, points, tol)[1]


def _coarse_index(s: NavSurface):
    """Lazily built coarse-node tables: (block_start CSR over blocks -> node order,
    node weight (sum of 1 / normal_y of its samples), node extent (max distance from the
    representative to a member sample), block grid shape)."""
    ci = s._cache.get("coarse_index")
    if ci is None:
        k = s.coarse_factor
        nx, nz = s.shape
        bx, bz = (nx + k - 1) // k, (nz + k - 1) // k
        rep = s.coarse_rep
        cells = s.cells[rep].astype(np.int64)
        blk = (cells[:, 0] // k) * bz + cells[:, 1] // k
        order = np.argsort(blk, kind="stable")
        bstart = np.zeros(bx * bz + 1, dtype=np.int64)
        np.cumsum(np.bincount(blk, minlength=bx * bz), out=bstart[1:])
        m = len(rep)
        w = np.bincount(s.coarse_of, 1.0 / s.normals[:, 1].astype(np.float64), minlength=m)
        d = np.linalg.norm(s.positions - s.positions[rep[s.coarse_of]], axis=1)
        morder, mptr = _members(s)
        ext = np.zeros(m)
        full = mptr[1:] > mptr[:-1]   # every node has its representative; keep the contract
        if full.any():   # sorted segments + reduceat: ~20x faster than np.maximum.at
            ext[full] = np.maximum.reduceat(d[morder], mptr[:-1][full])
        ci = (order, bstart, w, ext, (bx, bz))
        s._cache["coarse_index"] = ci
    return ci


def _jitter(s: NavSurface, k: int, p: np.ndarray, radius: float, rng) -> np.ndarray | None:
    """A point uniform in sample k's cell, on its tangent plane; None when outside radius."""
    q = s.positions[k].astype(np.float64)
    jx, jz = (rng.random(2) - 0.5) * s.cell_size * 0.999
    q[0] += jx
    q[2] += jz
    q[1] = _plane_y(s, k, q[0], q[2])
    return q if np.dot(q - p, q - p) <= radius * radius else None


def random_point_near(s: NavSurface, p, radius: float,
                      rng: np.random.Generator) -> np.ndarray | None:
    """A random walkable point within `radius` (3D) of p, in the component of the surface
    nearest p (so reachable from there), uniform by surface area over every layer (an upper
    floor, a bridge and the road under it each get their share; with a radius larger than
    the level, the whole reachable component): a sample is drawn with weight 1 / normal_y
    (its cell's true surface area, so a slope counts for more than its footprint), then
    jittered inside its cell on its tangent plane (rejected and redrawn when that leaves the
    sphere).
    Large radii draw a coarse node first (weight = its area), then a member sample, with
    rejection outside the sphere: still exactly uniform.
    Returns (3,) float64, or None when no such point exists."""
    p = _pt(p)
    s0, _ = _nearest_sample(s, p)
    if s0 < 0 or not radius > 0:
        return None
    comp = s.component[s0]
    if radius > 4 * s.coarse_factor * s.cell_size:
        q = _random_point_coarse(s, p, radius, comp, rng)
        if q is not None:
            return q
    ix0, iz0 = _columns(s, p[0] - radius, p[2] - radius)
    ix1, iz1 = _columns(s, p[0] + radius, p[2] + radius)
    idx = _window(s, ix0, ix1, iz0, iz1)
    if len(idx) == 0:
        return None
    idx = idx[s.component[idx] == comp]
    pos = s.positions[idx].astype(np.float64)
    d2 = np.einsum("ij,ij->i", pos - p, pos - p)
    idx = idx[d2 <= radius * radius]
    if len(idx) == 0:
        return None
    w = np.cumsum(1.0 / s.normals[idx, 1].astype(np.float64))
    for _ in range(32):
        k = idx[min(int(np.searchsorted(w, rng.random() * w[-1], side="right")), len(idx) - 1)]
        q = _jitter(s, k, p, radius, rng)
        if q is not None:
            return q
    return s.positions[k].astype(np.float64)


def _random_point_coarse(s: NavSurface, p, radius, comp, rng, tries: int = 64):
    cand = _coarse_candidates(s, p, radius, comp)
    if cand is None:
        return None
    nodes, cw = cand
    morder, mptr = _members(s)
    for _ in range(tries):
        u = nodes[min(int(np.searchsorted(cw, rng.random() * cw[-1], side="right")),
                      len(nodes) - 1)]
        mem, mw = _member_weights(s, int(u), morder, mptr)
        kk = mem[min(int(np.searchsorted(mw, rng.random() * mw[-1], side="right")), len(mem) - 1)]
        q = _jitter(s, int(kk), p, radius, rng)
        if q is not None:
            return q
    return None  # mostly outside the sphere: let the fine path decide


def _coarse_candidates(s: NavSurface, p, radius, comp):
    """(nodes, their cumulative area weights) of _random_point_coarse: the coarse nodes of
    component `comp` that may hold a point within `radius` of p, or None. Remembered per
    surface from a draw's second time round the same point at the same radius (a crowd's
    starts draw round one point at a few radii again and again; a wander target's point is
    new each time, and a level-wide radius's candidates are large)."""
    key = (float(p[0]), float(p[1]), float(p[2]), float(radius), int(comp))
    kept = _kept(s, "coarse_candidates", _CANDIDATES_KEPT, dict)
    if key in kept:
        return kept[key]
    out = _coarse_candidates_of(s, p, radius, comp)
    seen = _kept(s, "coarse_draws_seen", _SEEN_KEPT, set)
    if key in seen:
        kept[key] = out
    else:
        seen.add(key)
    return out


def _member_weights(s: NavSurface, u: int, morder, mptr):
    """(samples, cumulative 1 / normal_y) of coarse node u's members, remembered per surface."""
    kept = _kept(s, "member_weights", _MEMBERS_KEPT, dict)
    out = kept.get(u)
    if out is None:
        mem = morder[mptr[u]:mptr[u + 1]]
        out = kept[u] = (mem, np.cumsum(1.0 / s.normals[mem, 1].astype(np.float64)))
    return out


def _coarse_candidates_of(s: NavSurface, p, radius, comp):
    order, bstart, w, ext, (bx, bz) = _coarse_index(s)
    k, c = s.coarse_factor, s.cell_size
    bc = k * c
    i0 = int(math.floor((p[0] - radius - s.origin[0]) / bc)) - 1
    i1 = int(math.floor((p[0] + radius - s.origin[0]) / bc)) + 1
    j0 = int(math.floor((p[2] - radius - s.origin[1]) / bc)) - 1
    j1 = int(math.floor((p[2] + radius - s.origin[1]) / bc)) + 1
    i0, j0, i1, j1 = max(i0, 0), max(j0, 0), min(i1, bx - 1), min(j1, bz - 1)
    if i0 > i1 or j0 > j1:
        return None
    rows = np.arange(i0, i1 + 1, dtype=np.int64) * bz
    a, b = bstart[rows + j0], bstart[rows + j1 + 1]
    ln = b - a
    tot = int(ln.sum())
    if tot == 0:
        return None
    nodes = order[np.repeat(a - np.concatenate([[0], np.cumsum(ln)[:-1]]), ln)
                  + np.arange(tot, dtype=np.int64)]
    rep = s.coarse_rep[nodes]
    nodes = nodes[s.component[rep] == comp]
    rep = s.coarse_rep[nodes]
    dr = np.linalg.norm(s.positions[rep].astype(np.float64) - p, axis=1)
    nodes = nodes[dr <= radius + ext[nodes]]
    if len(nodes) == 0:
        return None
    return nodes, np.cumsum(w[nodes])


def _walk(s: NavSurface, s0: int, a: np.ndarray, b: np.ndarray, s1: int = -1):
    """Follow links from sample s0 (whose column holds a) along the straight XZ segment a-b.
    Returns the sample reached in b's column, or -1 when a column on the way has no linked
    sample on this layer (or the end is not s1 when s1 >= 0). Remembered per surface (paths
    planned again and again walk the same chains between the same points)."""
    key = (int(s0), float(a[0]), float(a[2]), float(b[0]), float(b[2]), int(s1))
    walks = _kept(s, "walks", _WALKS_KEPT, dict)
    out = walks.get(key)
    if out is None:
        out = walks[key] = _walk_links(s, s0, a, b, s1)
    return out


def _walk_links(s: NavSurface, s0: int, a: np.ndarray, b: np.ndarray, s1: int) -> int:
    """_walk's walk itself."""
    c = s.cell_size
    L = math.hypot(b[0] - a[0], b[2] - a[2])
    n = int(math.ceil(L / (0.25 * c))) + 1
    t = np.linspace(0.0, 1.0, n + 1)
    ix, iz = _columns(s, a[0] + t * (b[0] - a[0]), a[2] + t * (b[2] - a[2]))
    dx, dz = np.diff(ix), np.diff(iz)
    m = (dx != 0) | (dz != 0)
    dirs = _DIR_OF[dx[m] + 1, dz[m] + 1]
    cur = int(s0)
    if ix[0] != s.cells[cur, 0] or iz[0] != s.cells[cur, 1]:
        return -1
    links = s.links
    for d in dirs.tolist():
        cur = int(links[cur, d])
        if cur < 0:
            return -1
    if s1 >= 0 and cur != s1:
        return -1
    return cur


def _trace(s: NavSurface, s0: int, a: np.ndarray, b: np.ndarray, n: int):
    """Surface points at n + 1 evenly spaced XZ positions from a to b, on the layer reached
    by following links from s0 (whose column holds a) exactly as _walk does.
    Returns (points (n + 1, 3), ok); ok is False when the walk leaves the surface."""
    c = s.cell_size
    L = math.hypot(b[0] - a[0], b[2] - a[2])
    m = int(math.ceil(L / (0.25 * c))) + 1  # the same dense grid as _walk
    t = np.linspace(0.0, 1.0, m + 1)
    ix, iz = _columns(s, a[0] + t * (b[0] - a[0]), a[2] + t * (b[2] - a[2]))
    dx, dz = np.diff(ix), np.diff(iz)
    ch = np.nonzero((dx != 0) | (dz != 0))[0]
    dirs = _DIR_OF[dx[ch] + 1, dz[ch] + 1].tolist()
    samp = np.empty(m + 1, dtype=np.int64)
    cur = int(s0)
    ok = bool(ix[0] == s.cells[cur, 0] and iz[0] == s.cells[cur, 1])
    prev = 0
    for i, d in zip(ch.tolist(), dirs):
        samp[prev:i + 1] = cur
        nxt = int(s.links[cur, d]) if ok else -1
        if nxt < 0:
            ok = False
        else:
            cur = nxt
        prev = i + 1
    samp[prev:] = cur
    tk = np.linspace(0.0, 1.0, n + 1)
    k = np.rint(tk * m).astype(np.int64)
    x = a[0] + tk * (b[0] - a[0])
    z = a[2] + tk * (b[2] - a[2])
    # use the walked sample of the output point's own column (a nearby dense point holds it)
    oix, oiz = _columns(s, x, z)
    kk = k.copy()
    found = (ix[k] == oix) & (iz[k] == oiz)
    for off in (-1, 1, -2, 2, -3, 3):
        kc = np.clip(k + off, 0, m)
        hit = ~found & (ix[kc] == oix) & (iz[kc] == oiz)
        kk[hit] = kc[hit]
        found |= hit
    use = samp[kk]
    if not found.all():  # the segment only clips that column: step over to it by a link
        j = np.nonzero(~found)[0]
        ddx, ddz = oix[j] - ix[k[j]], oiz[j] - iz[k[j]]
        near = (np.abs(ddx) <= 1) & (np.abs(ddz) <= 1)
        j, ddx, ddz = j[near], ddx[near], ddz[near]
        nb = s.links[samp[k[j]], _DIR_OF[ddx + 1, ddz + 1]]
        use[j[nb >= 0]] = nb[nb >= 0]
    y = _plane_y(s, use, x, z)
    return np.stack([x, y, z], axis=1), ok


def resample_path(s: NavSurface, points, spacing: float | None = None) -> np.ndarray:
    """Points along a path (e.g. PathResult.points) every `spacing` metres (horizontal,
    default: the cell size), with heights on the surface layer the path walks on (the
    straight chord between two path points can cut through bumps of the terrain).
    Returns (m, 3) float64, the original points included."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(pts) == 0:
        return pts.copy()
    spacing = s.cell_size if spacing is None else float(spacing)
    k, _ = _locate(s, pts[:1], max(s.step_height, s.cell_size))
    cur = int(k[0])
    out = [pts[:1]]
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, int(math.ceil(math.hypot(b[0] - a[0], b[2] - a[2]) / spacing)))
        seg = None
        if cur >= 0:
            seg, ok = _trace(s, cur, a, b, n)
            if not ok:
                seg = None
        if seg is None:  # not a walkable straight segment: nearest layer to the chord
            t = np.linspace(0.0, 1.0, n + 1)[:, None]
            seg = a + t * (b - a)
            h = _locate(s, seg, np.inf)[1]
            seg[:, 1] = np.where(np.isnan(h), seg[:, 1], h)
        out.append(seg[1:])
        kb, _ = _locate(s, b[None], max(s.step_height, s.cell_size))
        cur = int(kb[0])
    return np.concatenate(out)


def segment_visible(s: NavSurface, a, b) -> bool:
    """True when the straight segment from a to b (both near the surface) stays on linked
    walkable samples of one layer: an agent can walk it straight."""
    a, b = _pt(a), _pt(b)
    ka, _ = _locate(s, a[None], max(s.step_height, s.cell_size))
    kb, _ = _locate(s, b[None], max(s.step_height, s.cell_size))
    if ka[0] < 0 or kb[0] < 0:
        return False
    return _walk(s, int(ka[0]), a, b, int(kb[0])) >= 0


def _closest_in_component(s: NavSurface, comp: int, b: np.ndarray) -> int:
    reps = s.coarse_rep
    rc = np.nonzero(s.component[reps] == comp)[0]
    rp = s.positions[reps[rc]].astype(np.float64)
    d = np.linalg.norm(rp - b, axis=1)
    slack = 2.0 * s.coarse_factor * s.cell_size * math.sqrt(2.0) + s.coarse_factor * s.step_height
    near = rc[d <= d.min() + 2 * slack]
    order, indptr = _members(s)
    idx = np.concatenate([order[indptr[u]:indptr[u + 1]] for u in near.tolist()])
    dd = np.linalg.norm(s.positions[idx].astype(np.float64) - b, axis=1)
    return int(idx[int(np.argmin(dd))])


def _edge_length(p, q) -> float:
    """Euclidean distance between two (x, y, z) float triples (A*'s edge cost)."""
    return math.sqrt((q[0] - p[0]) ** 2 + (q[1] - p[1]) ** 2 + (q[2] - p[2]) ** 2)


#: _astar's cost of an expanded node (below any cost, so never improved on)
_CLOSED = -math.inf


def _astar(start: int, goal: int, edges, point) -> list[int] | None:
    """A* with Euclidean costs and heuristic.

    edges(u) -> iterable of (node id, edge length _edge_length); point(u) -> (x, y, z) floats.
    Returns the node path start..goal, or None when goal is unreachable.
    """
    sqrt, push, pop, inf = math.sqrt, heapq.heappush, heapq.heappop, math.inf
    gx, gy, gz = point(goal)
    # best cost so far per node; CLOSED once expanded (no new cost is below it: one look-up
    # both skips a closed node and compares with an open one's)
    g = {start: 0.0}
    g_of = g.get
    parent = {start: -1}
    ux, uy, uz = point(start)
    heap = [(sqrt((ux - gx) ** 2 + (uy - gy) ** 2 + (uz - gz) ** 2), 0.0, start)]
    while heap:
        _, gu, u = pop(heap)
        if u == goal:
            out = [u]
            while parent[out[-1]] >= 0:
                out.append(parent[out[-1]])
            return out[::-1]
        if g[u] == _CLOSED:
            continue
        g[u] = _CLOSED
        for v, w in edges(u):
            ng = gu + w
            if ng < g_of(v, inf):
                g[v] = ng
                parent[v] = u
                vx, vy, vz = point(v)
                push(heap, (ng + sqrt((vx - gx) ** 2 + (vy - gy) ** 2 + (vz - gz) ** 2), ng, v))
    return None


def _coarse_astar(s: NavSurface, u0: int, u1: int) -> list[int] | None:
    """A* over the coarse graph: _astar's path, compiled (navmesh.astar: node for node)."""
    from baker.navmesh.astar import coarse_astar

    return coarse_astar(*_coarse_arrays(s), u0, u1)


def _coarse_arrays(s: NavSurface) -> tuple:
    """The coarse graph as navmesh.astar reads it: CSR indptr, indices (int64) and the
    representatives' positions (N, 3) float64, built once."""
    c = s._cache.get("coarse_arrays")
    if c is None:
        c = s._cache["coarse_arrays"] = (
            np.ascontiguousarray(s.coarse_indptr, dtype=np.int64),
            np.ascontiguousarray(s.coarse_indices, dtype=np.int64),
            np.ascontiguousarray(s.positions[s.coarse_rep], dtype=np.float64))
    return c


def _coarse_astar_python(s: NavSurface, u0: int, u1: int) -> list[int] | None:
    """_coarse_astar in Python, through _astar (plain lists): the reference the compiled
    search is tested against."""
    indptr, indices, pos, adj = _coarse_lists(s)

    def edges(u):
        e = adj[u]
        if e is None:
            p = pos[u]
            e = adj[u] = [(v, _edge_length(p, pos[v])) for v in indices[indptr[u]:indptr[u + 1]]]
        return e

    return _astar(u0, u1, edges, pos.__getitem__)


def _fine_astar(s: NavSurface, a: int, b: int, allowed: set[int]) -> list[int] | None:
    """A* over sample links, restricted to samples whose coarse node is in `allowed`."""
    pos, co, links = s.positions, s.coarse_of, s.links

    def point(u):
        return tuple(pos[u].tolist())   # the same Python floats as float() of each element

    def edges(u):
        p = point(u)
        return [(v, _edge_length(p, point(v))) for v in links[u].tolist()
                if v >= 0 and int(co[v]) in allowed]

    return _astar(a, b, edges, point)


def find_path(s: NavSurface, a, b) -> PathResult:
    """Path from a to b on the surface.

    A* over the coarse graph (connected groups of samples in blocks of columns), whose
    representatives are linked by straight walks on the fine links (fine A* fills any gap),
    then line-of-sight smoothing (string pulling): consecutive points are mutually visible on
    the surface (the straight segment stays on linked samples of one layer). Points lie on
    the surface. When b is not reachable from a, the path ends at the reachable point closest
    to b and complete is False. When a is not near any surface, points is just [a].
    """
    a, b = _pt(a), _pt(b)
    sa, pa = _nearest_sample(s, a)
    if sa < 0:
        return PathResult(a[None].copy(), False)
    sb, pb = _nearest_sample(s, b)
    complete = True
    if sb < 0 or s.component[sb] != s.component[sa]:
        sb = _closest_in_component(s, int(s.component[sa]), b)
        pb = s.positions[sb].astype(np.float64)
        complete = False
    if sa == sb or _walk(s, sa, pa, pb, sb) >= 0:
        pts = [pa] if np.array_equal(pa, pb) else [pa, pb]
        return PathResult(np.array(pts), complete)
    cpath = _coarse_astar(s, int(s.coarse_of[sa]), int(s.coarse_of[sb]))
    if cpath is None:  # cannot happen on a consistent surface; keep the contract anyway
        return PathResult(pa[None].copy(), False)
    reps = s.coarse_rep
    chain_s = [sa] + [int(reps[u]) for u in cpath[1:-1]] + [sb]
    chain_p = [pa] + [s.positions[k].astype(np.float64) for k in chain_s[1:-1]] + [pb]
    # make consecutive chain points mutually visible (fine A* inside the two blocks)
    fs, fp = [chain_s[0]], [chain_p[0]]
    for i in range(1, len(chain_s)):
        if _walk(s, fs[-1], fp[-1], chain_p[i], chain_s[i]) < 0:
            centre = s.positions[fs[-1]].astype(np.float64)
            if not np.array_equal(fp[-1], centre):  # leave an off-centre start via its centre
                fs.append(fs[-1])
                fp.append(centre)
            allowed = {int(s.coarse_of[fs[-1]]), int(s.coarse_of[chain_s[i]])}
            sub = _fine_astar(s, fs[-1], chain_s[i], allowed)
            if sub is None:  # pragma: no cover - groups are connected by construction
                sub = _fine_astar(s, fs[-1], chain_s[i], set(range(len(reps))))
            for k in sub[1:-1]:
                fs.append(k)
                fp.append(s.positions[k].astype(np.float64))
            if len(sub) >= 2 and _walk(s, fs[-1], fp[-1], chain_p[i], chain_s[i]) < 0:
                # the end point is off-centre in its cell: step through the centre
                fs.append(chain_s[i])
                fp.append(s.positions[chain_s[i]].astype(np.float64))
        fs.append(chain_s[i])
        fp.append(chain_p[i])
    # string pulling: from each anchor jump to a far visible chain point (galloping search:
    # +1, +2, +4, ... until a point is hidden, then bisect; only visible jumps are taken)
    out_p = [fp[0]]
    anchor = 0
    m = len(fs)

    def vis(i, j):
        return _walk(s, fs[i], fp[i], fp[j], fs[j]) >= 0

    while anchor < m - 1:
        if vis(anchor, m - 1):
            j = m - 1
        else:
            good, step = anchor + 1, 1
            bad = m - 1
            while good + step < bad:
                if vis(anchor, good + step):
                    good += step
                    step *= 2
                else:
                    bad = good + step
                    break
            while bad - good > 1:
                mid = (good + bad) // 2
                if vis(anchor, mid):
                    good = mid
                else:
                    bad = mid
            j = good
        out_p.append(fp[j])
        anchor = j
    pts = np.array(out_p)
    keep = np.ones(len(pts), dtype=bool)
    keep[1:] = np.any(np.abs(np.diff(pts, axis=0)) > 0, axis=1)
    return PathResult(pts[keep], complete)
