"""Polygons to triangles: a fan where the polygon is convex, ear clipping where it is not.

A fan from a polygon's first corner covers a concave polygon wrongly: an L-shaped floor
started at an outer corner gets a triangle over the notch, wound the other way. OBJ and USD
levels keep their n-gons (and quads) as modelled, so their concave ones are cut by
mapbox_earcut in the polygon's own plane; the convex ones (nearly all) keep their fan.
"""

from __future__ import annotations

import numpy as np

#: a corner turns the other way when its turn's component along the polygon's normal is below
#: this share of the product of its two edges' lengths (sin of the turn: about 0.06 degrees)
CONCAVE_SIN = 1e-3


def fan(counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(T, 3) int64 triangles of each polygon's fan from its first corner (sum(counts - 2)
    rows, polygon by polygon). counts (P,) >= 3, indices (sum counts,) int."""
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    starts = np.cumsum(counts) - counts
    ntri = counts - 2
    if ntri.sum() == 0:
        return np.zeros((0, 3), np.int64)
    first = np.repeat(np.cumsum(ntri) - ntri, ntri)
    s = np.repeat(starts, ntri)
    k = np.arange(ntri.sum()) - first + 1
    return np.stack([indices[s], indices[s + k], indices[s + k + 1]], axis=1)


def triangulate(points: np.ndarray, counts: np.ndarray, indices: np.ndarray,
                bent: np.ndarray | None = None) -> np.ndarray:
    """(T, 3) int64 triangles of the polygons counts (P,) >= 3, indices (sum counts,) into
    points (V, 3): the fan of every convex polygon, and mapbox_earcut's triangles of each
    concave one (its corners projected on its plane; wound as the polygon is). Polygon by
    polygon, each's triangles in a row; a concave polygon's triangles that earcut drops (zero
    area: repeated or collinear corners) are left out, and one earcut cannot cut keeps its
    fan. bent: concave(points, counts, indices) when the caller has it."""
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    tris = fan(counts, indices)
    bad = np.flatnonzero(concave(points, counts, indices) if bent is None else bent)
    if len(bad) == 0:
        return tris
    keep = np.ones(len(tris), dtype=bool)
    row = np.cumsum(counts - 2) - (counts - 2)                 # each polygon's first triangle
    starts = np.cumsum(counts) - counts
    points = np.asarray(points, dtype=np.float64)
    for p in bad:
        corners = indices[starts[p]:starts[p] + counts[p]]
        cut = _ear_cut(points[corners])
        if cut is None:
            continue
        tris[row[p]:row[p] + len(cut)] = corners[cut]
        keep[row[p] + len(cut):row[p] + counts[p] - 2] = False
    return tris[keep]


def concave(points: np.ndarray, counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(P,) bool: the polygons with four or more corners of which a corner turns against the
    polygon's (Newell) normal, so that their fan would cover more than the polygon. A polygon
    of no area (a line, a point) is not concave."""
    counts = np.asarray(counts, dtype=np.int64)
    out = np.zeros(len(counts), dtype=bool)
    many = np.flatnonzero(counts >= 4)
    if len(many) == 0:
        return out
    starts = np.cumsum(counts) - counts
    c, s = counts[many], starts[many]
    owner = np.repeat(np.arange(len(many)), c)
    pos = np.arange(c.sum()) - np.repeat(np.cumsum(c) - c, c)       # corner within its polygon
    at = np.repeat(s, c)
    p = np.asarray(points, dtype=np.float64)
    here = p[np.asarray(indices, dtype=np.int64)[at + pos]]
    after = p[np.asarray(indices, dtype=np.int64)[at + (pos + 1) % np.repeat(c, c)]]
    # Newell's normal: the sum over edges of the cross products of the corners
    corner_cross = np.cross(here, after)
    normal = np.stack([np.bincount(owner, corner_cross[:, k], len(many)) for k in range(3)],
                      axis=1)
    edge = after - here                                             # corner k -> k + 1
    before = np.roll(edge, 1, axis=0)
    firsts = np.cumsum(c) - c
    before[firsts] = edge[firsts + c - 1]                           # each polygon's last edge
    turn = np.einsum("ij,ij->i", np.cross(before, edge), normal[owner])
    scale = (np.linalg.norm(before, axis=1) * np.linalg.norm(edge, axis=1)
             * np.linalg.norm(normal, axis=1)[owner])
    against = turn < -CONCAVE_SIN * scale
    hit = np.bincount(owner[against], minlength=len(many)) > 0
    out[many] = hit & (np.linalg.norm(normal, axis=1) > 0)
    return out


def _ear_cut(corners: np.ndarray) -> np.ndarray | None:
    """(n - 2 or fewer, 3) triangles (corner numbers) of the polygon corners (n, 3) by
    mapbox_earcut in its plane, wound as the polygon; None when earcut gives none."""
    import mapbox_earcut

    n = len(corners)
    normal = np.cross(corners, np.roll(corners, -1, axis=0)).sum(axis=0)
    normal /= np.linalg.norm(normal)
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)                     # (u, v, normal) right-handed: counter-clockwise
    rel = corners - corners.mean(axis=0)
    flat = np.stack([rel @ u, rel @ v], axis=1)
    cut = np.asarray(mapbox_earcut.triangulate_float64(flat, np.array([n], dtype=np.uint32)),
                     dtype=np.int64).reshape(-1, 3)
    if len(cut) == 0 or len(cut) > n - 2:
        return None
    a, b, c = (flat[cut[:, k]] for k in range(3))
    cw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    cut[cw] = cut[cw][:, ::-1]                  # each triangle counter-clockwise, as the polygon
    return cut
