"""Build a navigation surface (NavData, queried through query.NavSurface) from an Environment (Recast's build steps, done with rays and numpy).

Steps (all vectorized over columns / samples; rays are cast in batched chunks):
1. Column heightfield: cast a ray straight down through every column centre from above the
   scene, then again from just below each hit, until no column hits anything: every surface
   layer of every column is found (log top and the floor inside it, bridge and road).
   A downward ray sees a face from either side. A hit on a closed (watertight) mesh
   component either enters the solid (its top) or leaves it (the inside of its bottom shell,
   not a floor): told by the face's winding where the solid's faces agree (outward or
   inward, found from its signed volume), so that a hit lost to a coincident face (a slab
   resting on a lintel) can be restored; by counting hits down the column otherwise. A face
   of an open component is a floor only seen from the side its normal points to (as in
   Recast), unless the whole file is wound the other way round (_open_facing), or it is
   modelled double-sided.
2. Walkable samples: slope within max_slope and at least agent height of free space up to the
   next hit above.
3. Links between 4-neighbour samples whose heights differ by at most the step height and whose
   free spaces overlap by the agent height; a short horizontal ray at a small height above the
   higher sample breaks links through walls (zero-thickness walls included). Diagonal links
   need both L-shaped 4-link paths (no corner cutting).
4. Erosion by the agent radius: a multi-source distance on the link graph from the boundary
   (horizontal rays give the exact distance to walls next to boundary samples).
5. Islands smaller than `min_island_area` are dropped; components are labelled (largest = 0).
6. A coarse graph over blocks of columns, for fast path finding.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from baker.errors import NavError
from baker.geometry.arrays import unique
from baker.navmesh import budget, raster
from baker.navmesh.query import NavSurface
from baker.navmesh.surface import DIRS, OPPOSITE, NavData
from baker.parallel import in_background, thread_count, thread_map

log = logging.getLogger(__name__)

#: Vertical offset below a hit before casting again (metres).
LAYER_EPS = 1e-4
#: Safety cap on the number of layers per column.
MAX_PASSES = 256
#: Largest grid built in one piece (about 0.5 kB of peak memory per column): beyond it, build
#: raises NavError asking for a larger cell size or smaller bounds instead of running out of
#: memory.
MAX_COLUMNS = 40_000_000
#: Columns ray-cast and reduced to walkable samples at a time, over all threads (bounds the
#: per-hit memory: each of n threads takes bands of TILE_COLUMNS / n)
TILE_COLUMNS = 1 << 20
#: Samples linked at a time, over all threads (bounds the temporaries of the link tests)
TILE_SAMPLES = 1 << 19


def _tile(size: int) -> int:
    """A tile's share of `size` items in flight at once: size / the threads the build's tiles
    run on (the results do not depend on it)."""
    return max(1, size // thread_count())
#: A part narrower than this many cells in x and in z (a stem, a post) can stand between the
#: grid lines the links are tested along: the samples around it are kept clear of it
#: explicitly.
THIN_POST = 2.0


# --------------------------------------------------------------------------- ray casting
class _Caster:
    """The environment's batched Embree rays (baker.environment.rays), plus column helpers."""

    def __init__(self, env):
        self.rays = env.rays
        self.shift = self.rays.shift
        self.face_normals = self.rays.face_normals
        self.vertices, self.faces = self.rays.vertices, self.rays.faces

    def cast(self, origins: np.ndarray, directions: np.ndarray,
             max_distance: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(t (n,) float64, inf on a miss; prim (n,) int32, -1 on a miss)."""
        return self.rays.cast(origins, directions, max_distance)


def _welded(v: np.ndarray) -> np.ndarray:
    """(V,) int64: each vertex's id, vertices within 1e-6 of the mesh's extent welded."""
    lo = v.min(axis=0)
    ext = float((v.max(axis=0) - lo).max()) or 1.0
    q = np.round((v - lo) / (ext * 1e-6)).astype(np.int64)
    key = (q[:, 0] << 42) | (q[:, 1] << 21) | q[:, 2]
    return np.unique(key, return_inverse=True)[1].reshape(-1)


def _solid_components(mesh, consistent: bool = False) -> tuple:
    """Closed mesh components and how they are wound.

    Returns (face_comp (F,) int64: connected component of each face, vertices welded by
    position; closed (K,) bool: every edge of the component is shared by exactly two faces;
    wind (K,) int8: +1 when a closed component is consistently wound with outward normals
    (positive signed volume), -1 when consistently wound inward, 0 when not closed or not
    consistently wound). A file's winding convention therefore never matters, only whether a
    solid's faces agree with each other."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    if len(f) == 0:
        return np.zeros(0, np.int64), np.zeros(0, bool), np.zeros(0, np.int8)
    lo, hi = v.min(axis=0), v.max(axis=0)
    ext = float((hi - lo).max()) or 1.0
    vid = _welded(v)
    f0, f1, f2 = (np.ascontiguousarray(vid[f[:, k]]) for k in range(3))
    nv = int(vid.max()) + 1
    # the edges as wound (a -> b), without the collapsed ones, and each as (low, high)
    a, b = np.concatenate([f0, f1, f2]), np.concatenate([f1, f2, f0])
    real = a != b
    a, b = a[real], b[real]
    key = np.minimum(a, b) * nv + np.maximum(a, b)
    o = np.argsort(key)
    ks = key[o]
    head = np.ones(len(ks), dtype=bool)
    head[1:] = ks[1:] != ks[:-1]
    first = np.nonzero(head)[0]
    cnt = np.diff(np.append(first, len(ks)))
    uk = ks[first]
    # the vertex graph: each edge once, rows and their columns sorted (the canonical form
    # connected_components would make of it), float64 (its own type: no converted copy)
    indptr = np.zeros(nv + 1, dtype=np.int64)
    np.cumsum(np.bincount(uk // nv, minlength=nv), out=indptr[1:])
    ncomp, vcomp = connected_components(_graph(uk % nv, indptr), directed=True,
                                        connection="weak")
    closed = np.ones(ncomp, dtype=bool)
    closed[vcomp[(uk[cnt != 2] // nv)]] = False
    # consistently wound: each edge is used once in each direction. Only closed components
    # (every edge used exactly twice) are judged, so it is enough that the two uses of such
    # an edge go opposite ways
    uniq_d = np.ones(ncomp, dtype=bool)
    fwd = (a < b)[o]
    two = first[cnt == 2]
    same_way = fwd[two] == fwd[two + 1]
    uniq_d[vcomp[uk[cnt == 2][same_way] // nv]] = False
    if consistent:     # each component's share of its two-face edges whose faces disagree
        # about the winding
        ec = vcomp[uk[cnt == 2] // nv]
        disagree = (np.bincount(ec, weights=same_way, minlength=ncomp)
                    / np.maximum(np.bincount(ec, minlength=ncomp), 1))
    fc = vcomp[f0]
    vol = np.bincount(fc, _signed_volumes(v - (lo + 0.5 * (hi - lo)), f), minlength=ncomp)
    closed &= np.abs(vol) > 1e-15 * ext ** 3  # a flat closed sheet (a two-sided triangle)
    wind = np.where(closed & uniq_d, np.sign(vol), 0).astype(np.int8)
    if consistent:
        return fc, closed, wind, disagree
    return fc, closed, wind


def _signed_volumes(c: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(F,) six times the signed volume of each face's tetrahedron with the origin,
    c[f0] . (c[f1] x c[f2]), on coordinate arrays (several times faster than np.cross and
    einsum on (F, 3) rows)."""
    p = [np.ascontiguousarray(c[:, j]) for j in range(3)]
    a, b, d = ([q[f[:, k]] for q in p] for k in range(3))
    return (a[0] * (b[1] * d[2] - b[2] * d[1]) + a[1] * (b[2] * d[0] - b[0] * d[2])
            + a[2] * (b[0] * d[1] - b[1] * d[0]))


# --------------------------------------------------------------------------- build steps
def _grid(env, bounds, cell: float):
    eb = np.asarray(env.bounds, dtype=np.float64)
    b = eb if bounds is None else np.asarray(bounds, dtype=np.float64)
    if b.shape == (2, 2):  # (x, z) min / max
        b = np.array([[b[0, 0], eb[0, 1], b[0, 1]], [b[1, 0], eb[1, 1], b[1, 1]]])
    x0, z0 = float(b[0, 0]), float(b[0, 2])
    nx = max(1, int(math.ceil((b[1, 0] - x0) / cell - 1e-9)))
    nz = max(1, int(math.ceil((b[1, 2] - z0) / cell - 1e-9)))
    return x0, z0, nx, nz, float(eb[1, 1]) + 1.0


def _layer_eps(caster: _Caster, x0, z0, nx, nz, cell, ytop) -> float:
    """How far below a surface the next layer of a column starts (closer hits are the same
    layer): as for float32 rays through the (re-centred) coordinates."""
    span = np.abs(np.array([x0, ytop, z0, x0 + nx * cell, z0 + nz * cell]) - np.r_[
        caster.shift[[0, 1, 2, 0, 2]]]).max()
    return max(LAYER_EPS, 16.0 * float(np.finfo(np.float32).eps) * span)


#: a file whose open surfaces' flat faces face down over more than this share of their area is
#: taken as wound the other way round throughout (a terrain exported with flipped normals)
FLIPPED_SHARE = 0.9
#: an open component whose faces disagree about the winding along more than this share of
#: their shared edges is walked on from either side (a shell level's joins disagree along
#: 0.2 % of them, a mesh wound at random along half)
MIXED_SHARE = 0.1


def _solids(mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
    """_solid_components of the mesh, _open_facing of its open components and which faces
    are walked on from either side: a closed solid's (its inside is told from its winding,
    _inside_solid), an open component's whose faces disagree about the winding along more
    than MIXED_SHARE of their shared edges (a mesh wound at random: its winding says
    nothing), and a triangle modelled twice (a double-sided floor: the same corners, welded
    as _solid_components welds them, either winding)."""
    face_comp, closed, wind, disagree = _solid_components(mesh, consistent=True)
    if len(face_comp) == 0:
        return face_comp, closed, wind, 1.0, np.zeros(0, dtype=bool)
    either = (closed | (disagree > MIXED_SHARE))[face_comp]
    f = np.asarray(mesh.faces, dtype=np.int64)
    if len(f) > 1:
        corners = np.sort(_welded(np.asarray(mesh.vertices, dtype=np.float64))[f], axis=1)
        _, inv, cnt = np.unique(corners, axis=0, return_inverse=True, return_counts=True)
        either = either | (cnt[inv.reshape(-1)] > 1)
    return face_comp, closed, wind, _open_facing(mesh, either), either


def _open_facing(mesh, either: np.ndarray) -> float:
    """Which side of the faces of open (not closed) mesh components is walked on (either:
    (F,) the faces walked on from either side, which have no say): +1.0 the
    side their normals (as wound) point to, as engines walk them (Recast, Unity and Godot
    build on up-facing triangles only), -1.0 the other, for a file wound the other way round
    throughout (its flat open faces mostly face down: more than FLIPPED_SHARE of their area).
    A level modelled as the inside of a shell (Recast's dungeon, a Quake-style arena) has
    open faces both ways, floors up and ceilings down: seen from above, a ceiling's back is
    the roof outside the level and the bottom's back the void under it, neither walkable."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    if len(f) == 0:
        return 1.0
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    twice = np.sqrt(np.einsum("ij,ij->i", n, n))
    ny = n[:, 1] / np.maximum(twice, 1e-300)
    flat = ~either & (np.abs(ny) >= 0.5)
    up, down = (float(twice[flat & side].sum()) for side in (ny > 0, ny < 0))
    return -1.0 if down > FLIPPED_SHARE * (up + down) else 1.0


def _walkable_hits(caster, tri, eps, c0, c1, solids, cos_slope, height, timings):
    """Heightfield of columns c0..c1-1 reduced to its walkable layers:
    (col, y, ceiling y, triangle, number of layers). tri: raster.Triangles of the grid; eps:
    _layer_eps of the grid; solids() gives _solids of the mesh. A layer is walked on from
    above only on the side _open_facing names of its open components' faces (any face of the
    layer), a closed solid's faces and a double-sided triangle's either way (_solids)."""
    t = time.perf_counter()
    hcol, hy, hprim = tri.layers(c0, c1)
    timings["layers"] = timings.get("layers", 0.0) + time.perf_counter() - t
    face_comp, comp_closed, comp_wind, facing, either = solids()
    t = time.perf_counter()
    face_ny = caster.face_normals[:, 1]
    hcol, hy, hprim, head = raster.coincident(
        hcol, hy, hprim, face_comp, face_ny, comp_wind[face_comp] != 0, eps, MAX_PASSES)
    first = np.ones(len(hcol), dtype=bool)
    first[1:] = hcol[1:] != hcol[:-1]
    # inside-solid test: a layer is not a floor when the space just above it lies inside a
    # closed component (its own exit, or a surface buried in / coincident with a solid),
    # judged on every crossing of the column, coincident ones included
    inside = _inside_solid(hcol, hprim, first, face_comp, comp_closed, comp_wind,
                           face_ny)[head]
    seen = either[hprim] | (face_ny[hprim] * facing > 0.0)
    front = (np.logical_or.reduceat(seen, np.nonzero(head)[0]) if len(seen)
             else np.zeros(0, dtype=bool))
    hcol, hy, hprim = hcol[head], hy[head], hprim[head]
    nh = len(hcol)
    first = np.ones(nh, dtype=bool)
    first[1:] = hcol[1:] != hcol[:-1]
    hceil = np.empty(nh)
    hceil[first] = np.inf
    hceil[~first] = hy[:-1][~first[1:]]
    hny = np.abs(face_ny[hprim])  # every hit is seen from above
    walk = (hny >= cos_slope) & (hceil - hy >= height) & ~inside & front
    out = (hcol[walk], hy[walk], hceil[walk], hprim[walk], nh)
    timings["samples"] = timings.get("samples", 0.0) + time.perf_counter() - t
    return out


def _inside_solid(hcol, hprim, first, face_comp, comp_closed, comp_wind,
                  face_ny) -> np.ndarray:
    """(H,) bool per hit (sorted by column, top to bottom): the space just above the hit lies
    inside a closed mesh component.

    face_ny : (F,) y of each face's normal as wound. A downward ray enters a consistently wound
    solid where its outward normal points up and leaves it where it points down, so hits on
    such solids are labelled by their winding; hits on closed solids with mixed winding
    alternate by count (the n-th hit enters when n is even). Two coincident faces (a slab
    resting on a lintel, a box standing on a floor) yield one hit, so a wound solid can lose an
    exit (or an entry): the lost exit is put at the next hit of the column below the entry,
    the lost entry at the hit just above the exit. (Counting alone would leave everything
    below such a contact inside the solid: the floor of a doorway under a lintel that carries
    an upper floor's slab.)"""
    nh = len(hcol)
    hc = face_comp[hprim]
    closed = comp_closed[hc]
    if not closed.any():
        return np.zeros(nh, dtype=bool)
    idx = np.nonzero(closed)[0]
    key = hcol[idx] * (len(comp_closed) + 1) + hc[idx]
    o = np.argsort(key, kind="stable")  # nearly sorted already: fast; keeps depth order
    si, key = idx[o], key[o]
    g = np.ones(len(si), dtype=bool)
    g[1:] = key[1:] != key[:-1]
    ar = np.arange(len(si))
    rank = ar - np.maximum.accumulate(np.where(g, ar, 0))
    up = np.sign(face_ny[hprim[si]] * comp_wind[hc[si]]).astype(np.int32)
    lab = np.where(up != 0, up, np.where(rank % 2 == 0, 1, -1)).astype(np.int32)
    toggle = np.zeros(nh, dtype=np.int32)
    toggle[si] = lab
    wound = up != 0
    if wound.any():
        prev = np.zeros(len(si), dtype=np.int32)
        prev[1:] = lab[:-1]
        prev[g] = 0
        last = np.ones(len(si), dtype=bool)
        last[:-1] = g[1:]
        nxt = np.zeros(len(si), dtype=np.int32)
        nxt[:-1] = lab[1:]
        nxt[last] = 0
        same_next = np.zeros(nh, dtype=bool)  # the next hit down is in the same column
        same_next[:-1] = ~first[1:]
        lost_exit = si[wound & (lab == 1) & (nxt != -1)]
        lost_exit = lost_exit[same_next[lost_exit]]
        toggle[lost_exit + 1] -= 1   # distinct hits: no repeated index
        lost_entry = si[wound & (lab == -1) & (prev != 1)]
        lost_entry = lost_entry[~first[lost_entry]]
        toggle[lost_entry - 1] += 1
    excl = np.cumsum(toggle) - toggle
    fidx = np.maximum.accumulate(np.where(first, np.arange(nh), 0))
    return (excl - excl[fidx]) > 0


def _riser(ya, yb, ga, gb):
    """Height of the step between two neighbouring samples, net of their surface slopes.

    ga, gb : rise of each sample's plane over the horizontal run between them. On a plane the
    riser is 0; across a crease it is at most half the slope change; on a vertical step it is
    the step's height. (Recast compares the raw height difference, which forces its climb limit
    up to cell * tan(max slope) just so that steep ramps stay connected.)
    """
    dy = yb - ya
    return np.minimum(np.abs(dy - ga), np.abs(dy - gb))


def _link_axis(d, rows, scol, six, siz, ys, ceil, nx, nz, col_start, counts, step, height,
               gs):
    """Best neighbour sample (or -1) of the samples `rows` (a slice) in axis direction d
    (0: +X, 1: +Z): the sample of the next column with the smallest riser, within the step
    height, with the agent height free above both. ys, ceil, gs : (n,) of every sample; gs is
    the rise of each sample's plane over one cell along d."""
    n = len(ys)
    scol, y, g = scol[rows], ys[rows], gs[rows]
    if d == 0:
        inb = six[rows] < nx - 1
        ncol = scol + nz
    else:
        inb = siz[rows] < nz - 1
        ncol = scol + 1
    ncol = np.where(inb, ncol, scol)
    cnt = np.where(inb, counts[ncol], 0)
    start = col_start[ncol]
    cand = np.minimum(start, n - 1)
    yc = ys[cand]
    dy = _riser(y, yc, g, gs[cand])
    cs = ceil[rows]
    gap = np.minimum(ceil[cand], cs) - np.maximum(yc, y)
    ok = (cnt > 0) & (dy <= step) & (gap >= height)
    best = np.where(ok, cand, -1)
    multi = np.nonzero(cnt > 1)[0]
    if len(multi):
        best_dy = np.where(ok, dy, np.inf)[multi]
        bm = best[multi]
        ym, cm_, gm, st, cm = y[multi], cs[multi], g[multi], start[multi], cnt[multi]
        for k in range(1, int(cm.max())):
            sel = np.nonzero(cm > k)[0]
            cand = st[sel] + k
            dy = _riser(ym[sel], ys[cand], gm[sel], gs[cand])
            gap = np.minimum(ceil[cand], cm_[sel]) - np.maximum(ys[cand], ym[sel])
            ok = (dy <= step) & (gap >= height) & (dy < best_dy[sel])
            bm[sel[ok]] = cand[ok]
            best_dy[sel[ok]] = dy[ok]
        best[multi] = bm
    return best


def _round_up(x: float) -> str:
    """x rounded up to 3 significant digits (a suggested cell size that is not below x)."""
    e = math.floor(math.log10(x)) - 2
    return f"{math.ceil(x / 10 ** e) * 10 ** e:.3g}"


def build(env, agent, **kw) -> NavSurface:
    """The navigation surface of `env` for `agent`, ready for queries: NavSurface(build_data(
    env, agent, **kw)) (see build_data)."""
    return NavSurface(build_data(env, agent, **kw))


def build_data(env, agent, *, bounds=None, coarse_factor: int = 4,
               min_island_area: float | None = None) -> NavData:
    """Build the navigation surface data of `env` for `agent` (a NavAgentConfig).

    bounds          : optional (2, 3) [min, max] corners (or (2, 2) XZ corners) limiting the
                      build area; default: the environment's bounds
    coarse_factor   : columns per side of a coarse path-finding block
    min_island_area : m^2, components with less horizontal area are dropped;
                      default max(64 cells, (4 radius)^2)
    Raises NavError when nothing is walkable.
    """
    with _small_pages():   # numpy's new arrays on ordinary pages
        return _build_data(env, agent, bounds, coarse_factor, min_island_area)


@contextlib.contextmanager
def _small_pages():
    """numpy's new arrays on ordinary 4 kB pages while the build runs: no MADV_HUGEPAGE, which
    numpy asks of arrays of 4 MB and more where transparent huge pages are on `madvise` (most
    Linux distributions). The build fills hundreds of fresh arrays of tens of MB, and there
    the kernel's work to find and clear huge pages cost more than it saved: the 1M-triangle
    build of benchmarks/bench_nav_recast.py took about 1 s (15 %) longer with them. The same
    values either way. The setting is numpy's own (NUMPY_MADVISE_HUGEPAGE at import), put back
    afterwards; where numpy has no such switch, nothing changes."""
    try:    # numpy 2, and numpy 1.26's forward-compatible alias of numpy.core
        from numpy._core.multiarray import _set_madvise_hugepage as toggle
    except ImportError:  # pragma: no cover - a numpy without the switch
        yield
        return
    before = toggle(False)
    try:
        yield
    finally:
        toggle(before)


def _build_data(env, agent, bounds, coarse_factor: int,
                min_island_area: float | None) -> NavData:
    """build_data's steps."""
    timings = {}
    t0 = time.perf_counter()
    cell = float(agent.cell_size)
    radius, height = float(agent.radius), float(agent.height)
    step, slope = float(agent.step_height), float(agent.max_slope)
    if not (cell > 0 and radius > 0 and height > 0 and step >= 0 and 0 <= slope < math.pi / 2):
        raise NavError(f"invalid navigation agent parameters: {agent}")
    mesh = env.mesh
    if len(mesh.faces) == 0:
        raise NavError("environment has no walkable surface (it has no triangles)",
                       where=env.source)
    x0, z0, nx, nz, ytop = _grid(env, bounds, cell)
    ncols = nx * nz
    budget.check(nx, nz, cell, len(mesh.faces), where=env.source,
                 hint="" if bounds is not None else
                 " (baker bake --nav-build lazy builds only where the creature goes)")
    if ncols > MAX_COLUMNS:
        raise NavError(f"navigation grid too large: {nx} x {nz} columns at cell size {cell:g} m "
                       f"(limit {MAX_COLUMNS:,}); use a larger cell size (at least "
                       f"{_round_up(cell * math.sqrt(ncols / MAX_COLUMNS))} m) or smaller bounds "
                       "(baker bake --nav-build lazy builds only where the creature goes)",
                       where=env.source)
    caster = _Caster(env)
    h_off = max(min(step, 0.5 * height), 1e-4)
    # while the columns are cast: the closed solids (read after the first columns), the
    # columns a steep face can block a link in (read by the links) and the thin upright parts
    # (read by the erosion)
    solids = in_background(_solids, mesh)
    blockers = in_background(_blocker_columns, caster, x0, z0, nx, nz, cell,
                             min(slope, math.atan2(h_off, cell)))
    posts = in_background(_thin_parts, caster, cell, slope)
    timings["setup"] = time.perf_counter() - t0

    grid = _Grid(x0, z0, nx, nz, cell)
    s = _samples(caster, grid, ytop, solids, slope, height, timings, env.source)
    t = time.perf_counter()
    links = _links(caster, grid, s, step, height, blockers(), h_off)
    timings["links"] = time.perf_counter() - t
    t = time.perf_counter()
    dist = _clearance(caster, grid, s, links, radius, h_off, posts(), height)
    s = s.slim()   # peak memory of the components and the coarse graph
    timings["erode"] = time.perf_counter() - t
    t = time.perf_counter()
    if min_island_area is None:
        min_island_area = max(64 * cell * cell, (4 * radius) ** 2)
    keep = dist >= radius - 1e-9
    groups = _groups(links, keep, s.ix, s.iz, coarse_factor, nz)
    sel, kept, comp, comp_area = _islands(links, keep, groups, cell, min_island_area,
                                          env.source)
    n_hits = s.n_hits
    # the kept samples' links renumbered on one thread while their other arrays and the coarse
    # graph (6.) are gathered on the other
    links, fields = thread_map(lambda task: task(), [
        lambda: _renumbered(links, kept),
        lambda: _kept_fields(s, dist, sel, groups, coarse_factor, ncols)])
    del s, dist, sel, kept   # the per-sample build arrays
    timings["components"] = time.perf_counter() - t
    timings["total"] = time.perf_counter() - t0
    log.info("navmesh: %d x %d columns, %d hits, %d walkable samples, %d components, "
             "%.3f m^2; %s", nx, nz, n_hits, len(comp), len(comp_area), comp_area.sum(),
             ", ".join(f"{k} {v:.3f}s" for k, v in timings.items()))
    return NavData(
        **fields,
        links=links,
        component=comp,
        component_area=comp_area,
        origin=(x0, z0),
        shape=(nx, nz),
        cell_size=cell,
        coarse_factor=int(coarse_factor),
        agent_radius=radius,
        agent_height=height,
        step_height=step,
        max_slope=slope,
    )


@dataclass(frozen=True)
class _Grid:
    """The column grid: origin (x0, z0) of its corner, nx x nz columns of `cell` metres."""

    x0: float
    z0: float
    nx: int
    nz: int
    cell: float


@dataclass
class _Samples:
    """Walkable samples, sorted by column (top to bottom within one).

    col, ix, iz   : (n,) column index and its grid coordinates
    px, pz        : (n,) the column centre
    y, ceil       : (n,) surface height and the height of what is above it
    normals       : (n, 3) upward surface normals
    col_start     : (ncols + 1,) first sample of each column; counts: (ncols,) samples in it
    n_hits        : ray hits the samples were chosen from
    """

    col: np.ndarray
    ix: np.ndarray
    iz: np.ndarray
    px: np.ndarray
    pz: np.ndarray
    y: np.ndarray
    ceil: np.ndarray | None
    normals: np.ndarray
    col_start: np.ndarray | None
    counts: np.ndarray | None
    n_hits: int

    def slim(self) -> "_Samples":
        """What the steps after erosion still read, in the dtypes the surface keeps (float32
        points and normals, int32 cells; no ceilings, no column index): about half the
        memory, and the same values in the end (each is rounded to float32 either way)."""
        f4, i4 = np.float32, np.int32
        return _Samples(self.col, self.ix.astype(i4), self.iz.astype(i4), self.px.astype(f4),
                        self.pz.astype(f4), self.y.astype(f4), None, self.normals.astype(f4),
                        None, None, self.n_hits)


def _samples(caster: _Caster, grid: _Grid, ytop, solids, slope, height, timings,
             where) -> _Samples:
    """1.-2. the column heightfield and its walkable samples, in bands of columns (bounded
    memory). solids(): _solids of the mesh."""
    x0, z0, nx, nz, cell = grid.x0, grid.z0, grid.nx, grid.nz, grid.cell
    ncols = nx * nz
    cos_slope = math.cos(slope) - 1e-9
    # the bands are independent, each on a thread (numpy and Embree release the GIL)
    band = _tile(TILE_COLUMNS)
    t = time.perf_counter()
    tri = raster.Triangles(caster.vertices, caster.faces, x0, z0, cell, nx, nz)
    eps = _layer_eps(caster, x0, z0, nx, nz, cell, ytop)
    timings["layers"] = time.perf_counter() - t

    def one(c0):
        col, y, ceil, prim, nh = _walkable_hits(caster, tri, eps, c0, min(ncols, c0 + band),
                                                solids, cos_slope, height, timings)
        t = time.perf_counter()
        nrm = caster.face_normals[prim]
        nrm *= np.where(nrm[:, 1] < 0, -1.0, 1.0)[:, None]
        ix, iz = col // nz, col % nz
        px, pz = x0 + (ix + 0.5) * cell, z0 + (iz + 0.5) * cell
        timings["samples"] = timings.get("samples", 0.0) + time.perf_counter() - t
        return (col, ix, iz, px, pz, y, ceil, nrm), nh

    parts = thread_map(one, range(0, ncols, band))
    nh = sum(p[1] for p in parts)
    t = time.perf_counter()
    fields = [[p[0][k] for p in parts] for k in range(8)]
    del parts
    scol, six, siz, px, pz, sy, sceil, snrm = thread_map(np.concatenate, fields)
    del fields
    if len(scol) == 0:
        raise NavError("environment has no walkable surface (no upward-facing surface within "
                       f"{math.degrees(slope):.1f} deg with {height:g} m of clearance)"
                       + _z_up_hint(caster.face_normals, cos_slope), where=where)
    counts = np.bincount(scol, minlength=ncols)
    col_start = np.zeros(ncols + 1, dtype=np.int64)
    np.cumsum(counts, out=col_start[1:])
    timings["samples"] += time.perf_counter() - t
    return _Samples(scol, six, siz, px, pz, sy, sceil, snrm, col_start, counts, nh)


def _z_up_hint(normals: np.ndarray, cos_slope: float) -> str:
    """A hint for a level with no walkable surface whose faces mostly face along Z (a +Z-up
    file read +Y up): '', or the --up option to try."""
    flat_y = np.count_nonzero(np.abs(normals[:, 1]) >= cos_slope)
    flat_z = np.count_nonzero(np.abs(normals[:, 2]) >= cos_slope)
    return "; its faces face along Z: if the level is +Z up, pass --up z" \
        if flat_z > max(flat_y, 0.25 * len(normals)) else ""


def _links(caster: _Caster, grid: _Grid, s: _Samples, step, height, blockers,
           h_off) -> np.ndarray:
    """3. (n, 8) int32 neighbour links of every sample (-1: none): a riser up to `step`, room
    for `height` above both, and no steep face between them (blockers: _blocker_columns).
    Tested in tiles of TILE_SAMPLES samples, so that the temporaries stay small (fresh large
    arrays cost page faults)."""
    nx, nz, cell = grid.nx, grid.nz, grid.cell
    scol, sy, sceil, counts = s.col, s.y, s.ceil, s.counts
    n = len(sy)
    links = np.full((n, 8), -1, dtype=np.int32)
    # rise of each sample's plane over one cell along +X and +Z (the diagonals: their sums)
    gx = -cell * s.normals[:, 0] / s.normals[:, 1]
    gz = -cell * s.normals[:, 2] / s.normals[:, 1]
    grad = {0: gx, 1: gz}

    def tile(d_r0):
        d, r0 = d_r0
        nb = _link_axis(d, slice(r0, min(n, r0 + size)), scol, s.ix, s.iz, sy, sceil, nx, nz,
                        s.col_start, counts, step, height, grad[d])
        src = np.nonzero(nb >= 0)[0]
        tt = nb[src]
        src += r0
        return _unblocked(caster, s, blockers, d, src, tt, h_off, cell)

    # the tiles are found on threads, and written in sample order (as in one piece)
    size = _tile(TILE_SAMPLES)
    tiles = [(d, r0) for d in (0, 1) for r0 in range(0, n, size)]
    for (d, _), (src, tt) in zip(tiles, thread_map(tile, tiles)):
        links[src, d] = tt
        links[tt, OPPOSITE[d]] = src
    # keep symmetric links only: two layers of one column may have claimed the same sample
    msrc = np.nonzero(counts[scol] > 1)[0]
    for d in (0, 1):
        src = msrc[links[msrc, d] >= 0]
        bad = links[links[src, d], OPPOSITE[d]] != src
        links[src[bad], d] = -1
    # the two diagonals read only axis links: found on threads, then written
    diagonals = ((4, (0, 1)), (7, (0, 3)))
    found = thread_map(lambda da: _diagonal(links, da[0], *da[1], sy, sceil, gx, gz, step,
                                            height), diagonals)
    for (d, _), (src, u) in zip(diagonals, found):
        links[src, d] = u
        links[u, OPPOSITE[d]] = src
    return links


def _unblocked(caster: _Caster, s: _Samples, blockers, d, src, tt, h_off, cell):
    """The links src -> tt (direction d) that no steep face blocks: a short horizontal ray
    from above the higher sample, cast only next to steep triangles (blocker columns)."""
    test = blockers[s.col[src]] | blockers[s.col[tt]]
    if not test.any():
        return src, tt
    q, qt = src[test], tt[test]
    o = np.stack([s.px[q], np.maximum(s.y[q], s.y[qt]) + h_off, s.pz[q]], axis=1)
    dirv = np.zeros_like(o)
    dirv[:, 0], dirv[:, 2] = DIRS[d]
    th, _ = caster.cast(o, dirv, cell)
    ok = np.ones(len(src), dtype=bool)
    ok[np.nonzero(test)[0][np.isfinite(th)]] = False
    return src[ok], tt[ok]


def _diagonal(links, d, a1, a2, sy, sceil, gx, gz, step, height):
    """Diagonal links (src, u) in direction d: both L-shaped paths of axis links (a1 then a2,
    a2 then a1) reach u, within the step height and with the agent height free above."""
    # the two axis columns, contiguous (gathers from the (n, 8) rows are strided); -1 (none)
    # reads the last sample, masked out
    l1, l2 = np.ascontiguousarray(links[:, a1]), np.ascontiguousarray(links[:, a2])
    u1 = np.where(l1 >= 0, l2[l1], -1)
    u2 = np.where(l2 >= 0, l1[l2], -1)
    src = np.nonzero((u1 >= 0) & (u1 == u2))[0]
    ok = np.empty(len(src), dtype=bool)
    for r0 in range(0, len(src), TILE_SAMPLES):
        r = slice(r0, r0 + TILE_SAMPLES)
        sr = src[r]
        u = u1[sr]
        gap = np.minimum(sceil[sr], sceil[u]) - np.maximum(sy[sr], sy[u])
        # the diagonal's rise, gx +/- gz, only where it is needed (the same sums, elementwise)
        ga = gx[sr] + gz[sr] if d == 4 else gx[sr] - gz[sr]
        gb = gx[u] + gz[u] if d == 4 else gx[u] - gz[u]
        ok[r] = (_riser(sy[sr], sy[u], ga, gb) <= step) & (gap >= height)
    src = src[ok]
    return src, u1[src]


def _clearance(caster: _Caster, grid: _Grid, s: _Samples, links, radius, h_off,
               posts=None, height: float = 0.0) -> np.ndarray:
    """4. (n,) each sample's distance to the walkable surface's edge (a wall or a drop), exact
    beside the edge and grown over the links up to `radius` (+inf farther in). `posts`
    (_thin_parts) are thin upright parts the links can pass between (a stem thinner than a
    cell): a sample whose agent space they stand in is on the edge too."""
    cell = grid.cell
    sy = s.y
    missing = links[:, :4] < 0
    border = np.nonzero(_row_counts(missing))[0]
    d0 = np.full(len(border), np.inf)
    bs, bd = np.nonzero(missing[border])
    if len(bs):  # exact distance to walls beside boundary samples
        sb = border[bs]
        o = np.stack([s.px[sb], sy[sb] + h_off, s.pz[sb]], axis=1)
        dirv = np.zeros_like(o)
        dirv[:, 0] = DIRS[bd, 0]
        dirv[:, 2] = DIRS[bd, 1]
        th, tp = caster.cast(o, dirv, cell)
        dd = np.full(len(th), 0.5 * cell)
        hit = np.isfinite(th)
        # distance to the wall's plane (a slanted wall is closer than along the grid axis)
        fn = caster.face_normals[tp[hit]]
        hlen = np.hypot(fn[:, 0], fn[:, 2])
        cosang = (np.abs(fn[:, 0] * dirv[hit, 0] + fn[:, 2] * dirv[hit, 2])
                  / np.maximum(hlen, 1e-12))
        dd[hit] = th[hit] * np.where(hlen > 1e-6, cosang, 1.0)
        d0 = _segment_min(bs, dd, len(border), np.inf)
    dist = np.full(len(sy), np.inf)
    dist[border] = d0
    if posts is not None and len(posts[0]):
        near, dp = _beside_posts(grid, s, posts, h_off, height)
        dist = np.minimum(dist, _segment_min(near, dp, len(dist), np.inf))
        border = unique(np.concatenate([border, near]))
    w = np.where(np.arange(8) < 4, cell, cell * math.sqrt(2.0))
    iters = int(math.ceil(radius / cell)) + 1
    active = border
    for _ in range(iters):
        if len(active) == 0:
            break
        changed = []
        for d in range(8):
            nb = links[active, d]
            m = nb >= 0
            src, nb = active[m], nb[m]
            nd = dist[src] + w[d]
            better = nd < dist[nb]
            if better.any():
                # a sample two links reach takes the smaller (numpy's own ufunc.at loop)
                nb = nb[better]
                np.minimum.at(dist, nb, nd[better])
                changed.append(nb)
        active = unique(np.concatenate(changed)) if changed else np.zeros(0, np.int64)
        active = active[dist[active] < radius + cell * 1.5]
    return dist


def _thin_parts(caster: _Caster, cell: float, slope: float):
    """The steep triangles (walls, sides) narrower than THIN_POST cells in x and in z, as
    (lo (K, 3), hi (K, 3)) bounding boxes. Link rays along the grid lines can pass on either
    side of such a triangle, and of a thin part made of them (a stem, a post); a wider one
    always crosses a grid line."""
    lo, hi = _steep_boxes(caster, slope)
    ext = hi - lo
    thin = (ext[:, 0] < THIN_POST * cell) & (ext[:, 2] < THIN_POST * cell)
    return lo[thin], hi[thin]


def _beside_posts(grid: _Grid, s: _Samples, posts, h_off: float, height: float):
    """(samples, their horizontal distances to a post's box): the samples in the columns a
    post's box covers whose agent space (h_off to height above the surface) the box reaches
    into (the clearance grows from them over the links)."""
    lo, hi = posts
    cell = grid.cell
    i0 = np.floor((lo[:, 0] - grid.x0) / cell).astype(np.int64)
    j0 = np.floor((lo[:, 2] - grid.z0) / cell).astype(np.int64)
    span = int(math.ceil(THIN_POST)) + 1           # columns a box can cover, per axis
    di, dj = np.meshgrid(np.arange(span), np.arange(span), indexing="ij")
    ci = (i0[:, None] + di.reshape(1, -1)).reshape(-1)
    cj = (j0[:, None] + dj.reshape(1, -1)).reshape(-1)
    k = np.repeat(np.arange(len(lo)), span * span)
    i1 = np.floor((hi[k, 0] - grid.x0) / cell)
    j1 = np.floor((hi[k, 2] - grid.z0) / cell)
    ok = (ci >= 0) & (ci < grid.nx) & (cj >= 0) & (cj < grid.nz) & (ci <= i1) & (cj <= j1)
    col, k = ci[ok] * grid.nz + cj[ok], k[ok]
    n = s.counts[col]
    first = np.repeat(s.col_start[col], n)
    smp = first + (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n))
    k = np.repeat(k, n)
    y = s.y[smp]
    reach = (lo[k, 1] < y + height) & (hi[k, 1] > y + h_off)
    smp, k = smp[reach], k[reach]
    dx = np.maximum(np.maximum(lo[k, 0] - s.px[smp], s.px[smp] - hi[k, 0]), 0.0)
    dz = np.maximum(np.maximum(lo[k, 2] - s.pz[smp], s.pz[smp] - hi[k, 2]), 0.0)
    return smp, np.hypot(dx, dz)


@dataclass(frozen=True)
class _Groups:
    """The kept samples' links split by the coarse blocks (k x k columns): the nodes of the
    coarse graph, found before the islands (whose components they make cheap to find).

    label : (n,) the connected group of each sample within its block (a sample not kept is a
            group of its own); groups are numbered in the order of their first sample
    count : the number of groups
    keys  : (K,) int64 g * count + h, sorted and unique: group g reaches group h over a +X or
            +Z link across a block border (the links are symmetric: so does h reach g)
    """

    label: np.ndarray
    count: int
    keys: np.ndarray


def _groups(links, keep, ix, iz, k, nz) -> _Groups:
    """The coarse graph's nodes and edges among the kept samples (keep (n,) bool; ix, iz (n,)
    their grid cells) in blocks of k x k columns. The links within blocks are gathered in
    tiles on threads."""
    k = max(1, int(k))
    n = len(links)
    block = (ix // k).astype(np.int64) * ((nz + k - 1) // k) + iz // k
    ax = links[:, :4]
    size = _tile(TILE_SAMPLES)

    def tile(r0):
        r = slice(r0, min(n, r0 + size))
        a = ax[r]
        has = (a >= 0) & keep[r, None] & keep[a]     # (-1, no link, reads the last: masked)
        same = has & (block[r, None] == block[np.maximum(a, 0)])
        # (samples within the block each links to, those links, the +X / +Z links leaving it)
        return _row_counts(same), a[same], has[:, :2] & ~same[:, :2]

    parts = thread_map(tile, range(0, n, size))
    indptr = np.zeros(n + 1, dtype=np.int32 if 4 * n < 2**31 else np.int64)
    np.cumsum(np.concatenate([p[0] for p in parts]), out=indptr[1:])
    inside = np.concatenate([p[1] for p in parts]).astype(np.int32, copy=False)
    leave = np.concatenate([p[2] for p in parts])
    del parts
    count, label = connected_components(_graph(inside, indptr), directed=True,
                                        connection="strong")
    keys = []
    for d in (0, 1):  # +X, +Z; symmetrized where they are read
        src = np.nonzero(leave[:, d])[0]
        key = label[src].astype(np.int64) * count + label[ax[src, d]]
        if len(key) > 1:  # neighbours along a block border mostly repeat the same pair
            key = key[np.concatenate([[True], key[1:] != key[:-1]])]
        keys.append(key)
    return _Groups(label, count, unique(np.concatenate(keys)))


def _graph(indices: np.ndarray, indptr: np.ndarray) -> csr_matrix:
    """The square graph with these rows (CSR structure) and unit weights, for
    connected_components: the weights are one float64 repeated (a zero-stride view: the
    search reads only the structure, and a fresh array of ones as long as the links costs
    their page faults); float64 is its own type, so it makes no converted copy."""
    n = len(indptr) - 1
    return csr_matrix((np.broadcast_to(np.float64(1.0), indices.shape), indices, indptr),
                      shape=(n, n))


def _row_counts(mask: np.ndarray) -> np.ndarray:
    """(n,) int32 the True entries of each row of mask (n, k) (column sums: several times
    faster than summing along the short rows)."""
    out = np.zeros(len(mask), dtype=np.int32)
    for j in range(mask.shape[1]):
        np.add(out, mask[:, j], out=out)
    return out


def _group_graph(keys: np.ndarray, count: int, on: np.ndarray | None = None):
    """(indptr, indices int32) of the symmetric graph of groups joined by `keys` (_Groups);
    with `on` (count,) bool, among those groups only, renumbered in order. Each row lists the
    groups its keys reach, then those reaching it (both ascending)."""
    cs, cd = np.divmod(keys, count)
    if on is not None:
        ok = on[cs] & on[cd]
        new = np.cumsum(on) - 1
        cs, cd, count = new[cs[ok]], new[cd[ok]], int(on.sum())
    cs, cd = np.concatenate([cs, cd]), np.concatenate([cd, cs])
    o = np.argsort(cs, kind="stable")
    cs, cd = cs[o], cd[o]
    indptr = np.zeros(count + 1, dtype=np.int64)
    np.cumsum(np.bincount(cs, minlength=count), out=indptr[1:])
    return indptr, cd.astype(np.int32)


def _islands(links, keep, groups: _Groups, cell, min_island_area, where):
    """5. the kept samples' connected components, dropping those under `min_island_area`.
    Returns (sel: the indices of the samples kept, the same as an (n,) mask (_renumbered),
    component of each (largest first), component areas).

    The components are those of the graph of the coarse groups (connected groups of samples
    inside one block, joined where a link crosses a block border): a graph of about a
    sixteenth of the samples. Its components come numbered as the samples' own would (in the
    order of their first sample: groups are numbered so), so the ties in size keep their
    order."""
    indptr, indices = _group_graph(groups.keys, groups.count)
    graph = _graph(indices, indptr)
    ncomp, of_group = connected_components(graph, directed=True, connection="strong")
    comp = of_group[groups.label]
    size = np.bincount(comp[keep], minlength=ncomp)
    big = size * cell * cell >= min_island_area
    keep2 = keep & big[comp]
    if not keep2.any():
        raise NavError("environment has no walkable surface (every walkable area is narrower "
                       f"than the agent or smaller than {min_island_area:g} m^2)",
                       where=where)
    sel = np.nonzero(keep2)[0]
    order = np.argsort(-size[big], kind="stable")
    relabel = np.full(ncomp, -1, dtype=np.int64)
    relabel[np.nonzero(big)[0][order]] = np.arange(int(big.sum()))
    comp = relabel[comp[sel]].astype(np.int32)
    comp_area = np.sort(size[big])[::-1] * cell * cell
    return sel, keep2, comp, comp_area


def _renumbered(links, kept) -> np.ndarray:
    """(m, 8) int32 the links of the kept samples (kept (n,) bool, m of them), renumbered to
    them (-1: none, or to a sample not kept)."""
    remap = np.full(len(kept) + 1, -1, dtype=np.int32)
    rows = np.flatnonzero(kept)
    remap[rows] = np.arange(len(rows), dtype=np.int32)
    out = np.empty((len(rows), links.shape[1]), dtype=np.int32)
    for r0 in range(0, len(rows), TILE_SAMPLES):   # bounded temporaries (peak memory)
        r = slice(r0, r0 + TILE_SAMPLES)
        remap.take(links[rows[r]], out=out[r])
    return out


def _kept_fields(s: _Samples, dist, sel, groups: _Groups, k: int, ncols: int) -> dict:
    """The NavData fields of the kept samples sel other than their links and components:
    positions, normals, cells, columns, clearance and the coarse graph (6.)."""
    counts = np.bincount(s.col[sel], minlength=ncols)
    col_start = np.zeros(ncols + 1, dtype=np.int64)
    np.cumsum(counts, out=col_start[1:])
    cells = np.stack([s.ix[sel], s.iz[sel]], axis=1)
    coarse_of, coarse_rep, indptr, indices = _coarse(cells, groups.label[sel], groups, k)
    return dict(positions=np.stack([s.px[sel], s.y[sel], s.pz[sel]], axis=1),
                normals=s.normals[sel], cells=cells, col_start=col_start,
                clearance=dist[sel].astype(np.float32), coarse_of=coarse_of,
                coarse_rep=coarse_rep, coarse_indptr=indptr, coarse_indices=indices)


def _blocker_columns(caster: _Caster, x0, z0, nx, nz, cell, angle) -> np.ndarray:
    """(nx * nz,) bool: columns within one cell of the XZ bounding box of a triangle steeper
    than `angle` (only those can block a horizontal link ray)."""
    lo, hi = _steep_boxes(caster, angle)
    if len(lo) == 0:
        return np.zeros(nx * nz, dtype=bool)
    i0 = np.clip(np.floor((lo[:, 0] - x0) / cell).astype(np.int64) - 1, 0, nx)
    i1 = np.clip(np.floor((hi[:, 0] - x0) / cell).astype(np.int64) + 2, 0, nx)
    j0 = np.clip(np.floor((lo[:, 2] - z0) / cell).astype(np.int64) - 1, 0, nz)
    j1 = np.clip(np.floor((hi[:, 2] - z0) / cell).astype(np.int64) + 2, 0, nz)
    w = nz + 1
    size = (nx + 1) * w
    # corner counts by bincount (exact integers), not np.add.at; summed in place
    diff = (np.bincount(np.concatenate([i0 * w + j0, i1 * w + j1]), minlength=size)
            - np.bincount(np.concatenate([i1 * w + j0, i0 * w + j1]), minlength=size))
    diff = diff.reshape(nx + 1, w)
    np.cumsum(diff, axis=0, out=diff)
    np.cumsum(diff, axis=1, out=diff)
    return (diff[:nx, :nz] > 0).reshape(-1)


def _steep_boxes(caster: _Caster, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """(lo (K, 3), hi (K, 3)) the bounding boxes of the triangles steeper than `angle`."""
    steep = np.nonzero(np.abs(caster.face_normals[:, 1]) < math.cos(angle) + 1e-9)[0]
    f = caster.faces[steep]
    a, b, c = (caster.vertices[f[:, k]] for k in range(3))
    return np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)


def _segment_min(group: np.ndarray, values: np.ndarray, n: int, empty) -> np.ndarray:
    """(n,) the smallest of `values` in each group 0..n-1 (`empty` where a group has none).
    np.minimum.at: since numpy 1.25 its loop is several times faster than sorting the groups
    and reducing their runs (0.03 s against 0.3 s for the coarse graph's 3.7 M samples)."""
    out = np.full(n, empty, dtype=values.dtype)
    np.minimum.at(out, group, values)
    return out


def _coarse(cells, group_of, groups: _Groups, k):
    """6. the coarse graph of the kept samples (cells (n, 2) theirs, group_of (n,) their
    groups): its nodes are those groups (_Groups), renumbered in order. Returns (node of each
    sample, representative sample of each node, indptr, indices)."""
    n = len(group_of)
    k = max(1, int(k))
    on = np.zeros(groups.count, dtype=bool)
    on[group_of] = True
    lab = (np.cumsum(on) - 1)[group_of]
    nc = int(on.sum())
    # representative: the sample nearest its block's centre (ties: lowest index)
    c = (k - 1) * 0.5
    pri = np.abs(cells[:, 0] % k - c) + np.abs(cells[:, 1] % k - c)
    key = np.rint(pri * 2).astype(np.int64) * n + np.arange(n)
    best = _segment_min(lab, key, nc, np.iinfo(np.int64).max)
    rep = (best % n).astype(np.int32)
    indptr, indices = _group_graph(groups.keys, groups.count, on)
    return lab.astype(np.int32), rep, indptr, indices
