"""Column layers by rasterizing the triangles, compiled with numba.

The navigation build needs, for every column of its grid, every surface the column's centre
line crosses, top to bottom: what repeated downward rays give, each re-cast a little below the
last hit. Rasterizing gives the same layers with no rays at all: each triangle visits the
column centres inside its XZ projection, row by row, and computes its height there from its
plane (in float64, relative to the grid's corner). A column's hits are sorted top to bottom
(`Triangles.layers`) and gathered into layers as the rays would see them (`coincident`): hits
less than `eps` below a layer's top are that layer, and unlike a ray's single hit, every
solid's crossing within it stays, for the build's inside-solid test.

Edges and corners are inclusive, so no column falls through a crack between two triangles; a
centre on a shared edge finds both, at the same height, and `coincident` keeps one. Vertical
triangles (no XZ area) are never hit, as a vertical ray misses them.

The compiled functions run off the main thread (parallel.off_main_thread): a signal handled
while numba boxes their results would crash the process.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from baker.parallel import off_main_thread


#: how far (in cells) a row's span is widened before the exact inside test
SPAN_MARGIN = 1e-6


class Triangles:
    """The mesh's triangles in grid coordinates, ready for any band of columns.

    Coordinates are relative to the grid's corner (x0, z0) in units of the cell for x and z;
    (ilo, ihi, klo, khi): the first and last column indices in x and in z whose centres can be
    inside each triangle's projection (ilo > ihi when none)."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, x0: float, z0: float,
                 cell: float, nx: int, nz: int):
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
        self.u = np.ascontiguousarray((v[:, 0] - x0) / cell - 0.5)   # column index space
        self.w = np.ascontiguousarray((v[:, 2] - z0) / cell - 0.5)
        self.y = np.ascontiguousarray(v[:, 1])
        self.f = np.ascontiguousarray(f)
        self.ilo, self.ihi, self.klo, self.khi = off_main_thread(_boxes, self.u, self.w,
                                                                  self.f, nx, nz)
        self.nz = nz

    def layers(self, c0: int, c1: int):
        """Every hit of columns c0..c1-1: (col (H,) int64, y (H,) float64, prim (H,) int32),
        sorted by column, then top to bottom (then by triangle)."""
        nz = self.nz
        i0, i1 = c0 // nz, (c1 - 1) // nz
        sel = np.nonzero((self.ilo <= i1) & (self.ihi >= i0) & (self.klo <= self.khi))[0]
        return off_main_thread(_layers, self.u, self.w, self.y, self.f, self.ilo, self.ihi,
                               self.klo, self.khi, sel, nz, c0, c1)


@njit(cache=True, nogil=True)
def _boxes(u, w, f, nx, nz):
    n = len(f)
    ilo, ihi = np.empty(n, np.int64), np.empty(n, np.int64)
    klo, khi = np.empty(n, np.int64), np.empty(n, np.int64)
    for t in range(n):
        a, b, c = f[t, 0], f[t, 1], f[t, 2]
        ilo[t] = max(0, np.ceil(min(u[a], u[b], u[c])))
        ihi[t] = min(nx - 1, np.floor(max(u[a], u[b], u[c])))
        klo[t] = max(0, np.ceil(min(w[a], w[b], w[c])))
        khi[t] = min(nz - 1, np.floor(max(w[a], w[b], w[c])))
    return ilo, ihi, klo, khi


@njit(cache=True, nogil=True, inline="always")
def _hit(u, w, y, a, b, c, pu, pw):
    """Height of triangle (a, b, c) over the point (pu, pw), NaN when the point is outside its
    projection (edges inclusive) or the projection has no area."""
    ua, wa, ub, wb, uc, wc = u[a], w[a], u[b], w[b], u[c], w[c]
    area = (ub - ua) * (wc - wa) - (uc - ua) * (wb - wa)
    if area == 0.0:
        return np.nan
    e0 = (ub - pu) * (wc - pw) - (uc - pu) * (wb - pw)   # opposite a
    e1 = (uc - pu) * (wa - pw) - (ua - pu) * (wc - pw)   # opposite b
    e2 = (ua - pu) * (wb - pw) - (ub - pu) * (wa - pw)   # opposite c
    if area > 0.0:
        if e0 < 0.0 or e1 < 0.0 or e2 < 0.0:
            return np.nan
    elif e0 > 0.0 or e1 > 0.0 or e2 > 0.0:
        return np.nan
    return (e0 * y[a] + e1 * y[b] + e2 * y[c]) / area


@njit(cache=True, nogil=True, inline="always")
def _row_span(u, w, a, b, c, pu, klo, khi):
    """The column indices in z whose centres on the row u = pu can be inside the triangle's
    projection: where the row crosses its edges, widened by a hair (the exact test decides)."""
    lo, hi = np.inf, -np.inf
    for p, q in ((a, b), (b, c), (c, a)):
        up, uq = u[p], u[q]
        if min(up, uq) <= pu <= max(up, uq):
            if up == uq:
                lo, hi = min(lo, w[p], w[q]), max(hi, w[p], w[q])
            else:
                x = w[p] + (pu - up) * (w[q] - w[p]) / (uq - up)
                lo, hi = min(lo, x), max(hi, x)
    if lo > hi:
        return 0, -1
    return max(klo, int(np.ceil(lo - SPAN_MARGIN))), min(khi, int(np.floor(hi + SPAN_MARGIN)))


@njit(cache=True, nogil=True)
def _scan(u, w, y, f, ilo, ihi, klo, khi, sel, nz, c0, c1, fill, hy, hp, store):
    """Every hit of a triangle of `sel` in columns c0..c1-1: counted in fill[col - c0], or
    (store) written at hy, hp[fill[col - c0]], which then moves on by one."""
    i0, i1 = c0 // nz, (c1 - 1) // nz
    for t in sel:
        a, b, c = f[t, 0], f[t, 1], f[t, 2]
        for i in range(max(ilo[t], i0), min(ihi[t], i1) + 1):
            k0, k1 = _row_span(u, w, a, b, c, float(i), klo[t], khi[t])
            for k in range(k0, k1 + 1):
                col = i * nz + k
                if col < c0 or col >= c1:
                    continue
                h = _hit(u, w, y, a, b, c, float(i), float(k))
                if not np.isnan(h):
                    j = fill[col - c0]
                    if store:
                        hy[j] = h
                        hp[j] = t
                    fill[col - c0] = j + 1


@njit(cache=True, nogil=True)
def _layers(u, w, y, f, ilo, ihi, klo, khi, sel, nz, c0, c1):
    ncol = c1 - c0
    counts = np.zeros(ncol + 1, np.int64)           # 1. how many hits each column has
    _scan(u, w, y, f, ilo, ihi, klo, khi, sel, nz, c0, c1, counts[1:], np.empty(0),
          np.empty(0, np.int32), False)
    start = np.cumsum(counts)
    hy = np.empty(start[-1], np.float64)            # 2. the hits, column by column
    hp = np.empty(start[-1], np.int32)
    _scan(u, w, y, f, ilo, ihi, klo, khi, sel, nz, c0, c1, start[:-1].copy(), hy, hp, True)
    out_c = np.empty(start[-1], np.int64)
    for q in range(ncol):                           # 3. each column top to bottom
        s, e = start[q], start[q + 1]
        out_c[s:e] = c0 + q
        for j in range(s + 1, e):                   # insertion sort: y down, then triangle up
            vy, vp = hy[j], hp[j]
            m = j - 1
            while m >= s and (hy[m] < vy or (hy[m] == vy and hp[m] > vp)):
                hy[m + 1] = hy[m]
                hp[m + 1] = hp[m]
                m -= 1
            hy[m + 1] = vy
            hp[m + 1] = vp
    return out_c, hy, hp


def coincident(col, y, prim, comp, face_ny, wound, eps: float, max_passes: int) -> tuple:
    """The hits of layers() gathered into layers as a ray would see them: a layer starts at
    the highest hit not yet taken and holds every hit less than `eps` below it, at most
    `max_passes` layers a column. Within a layer, a hit of the same mesh component as one
    already in it, facing the same way when the component is consistently wound (two
    triangles meeting where the column crosses their edge), is dropped, and the flattest hit
    goes first: it is the layer's surface.

    comp : (F,) mesh component of each face; face_ny : (F,) y of each face's normal as wound;
    wound : (F,) bool, the face's component is consistently wound (its faces' sides mean
    something).
    Returns (col, y, prim, head): the hits kept, in column order, top to bottom by layer, and
    head (H,) bool marking each layer's surface (its first hit)."""
    return off_main_thread(_coincident, col, y, prim, comp, face_ny, wound, eps, max_passes)


@njit(cache=True, nogil=True)
def _coincident(col, y, prim, comp, ny, wound, eps, max_passes):
    n = len(col)
    oc, oy = np.empty(n, np.int64), np.empty(n, np.float64)
    op, head = np.empty(n, np.int32), np.zeros(n, np.bool_)
    m = 0
    s = 0
    while s < n:
        e = s
        while e < n and col[e] == col[s]:
            e += 1
        j, layers = s, 0
        while j < e and layers < max_passes:
            g0, best, below = m, m, y[j] - eps
            while j < e and y[j] > below:
                p = prim[j]
                dup = False
                for q in range(g0, m):
                    if comp[op[q]] == comp[p] and (
                            not wound[p] or (ny[op[q]] > 0) == (ny[p] > 0)):
                        dup = True
                        break
                if not dup:
                    oc[m], oy[m], op[m] = col[j], y[j], p
                    if abs(ny[p]) > abs(ny[op[best]]):
                        best = m
                    m += 1
                j += 1
            oy[g0], oy[best] = oy[best], oy[g0]
            op[g0], op[best] = op[best], op[g0]
            head[g0] = True
            layers += 1
        s = e
    return oc[:m], oy[:m], op[:m], head[:m]
