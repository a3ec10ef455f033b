"""Exact point-to-triangle-mesh distances within a cap (pure numpy/scipy).

Used to judge contacts from the files alone: a foot is "on the ground" when its distance to the
nearest surface (any direction, walls included) is small. Only distances up to a cap are needed,
so candidate (point, triangle) pairs come from a KD-tree over the points queried with each
triangle's bounding sphere grown by the cap; every pair then gets an exact closest-point test.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: (point, triangle) pairs tested per batch (bounds the temporary arrays)
PAIR_CHUNK = 1 << 20


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(n, 3) closest points on triangles (a, b, c) to points p, all (n, 3) float
    (Ericson, Real-Time Collision Detection 5.1.5, vectorized over the Voronoi regions)."""
    ab, ac, ap = b - a, c - a, p - a
    d1 = np.einsum("ij,ij->i", ab, ap)
    d2 = np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3 = np.einsum("ij,ij->i", ab, bp)
    d4 = np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5 = np.einsum("ij,ij->i", ab, cp)
    d6 = np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 1.0 / (va + vb + vc)
        v = vb * denom
        w = vc * denom
        out = a + ab * v[:, None] + ac * w[:, None]                     # face interior
        # edges
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        t_ac = d2 / (d2 - d6)
        t_ab = d1 / (d1 - d3)
    m = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
    out[m] = b[m] + (c[m] - b[m]) * t_bc[m, None]
    m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    out[m] = a[m] + ac[m] * t_ac[m, None]
    m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    out[m] = a[m] + ab[m] * t_ab[m, None]
    # vertices (checked last: they win where regions overlap numerically)
    m = (d6 >= 0) & (d5 <= d6)
    out[m] = c[m]
    m = (d3 >= 0) & (d4 <= d3)
    out[m] = b[m]
    m = (d1 <= 0) & (d2 <= 0)
    out[m] = a[m]
    bad = ~np.all(np.isfinite(out), axis=1)         # degenerate triangles: nearest vertex
    if bad.any():
        cand = np.stack([a[bad], b[bad], c[bad]], 1)
        k = np.argmin(np.linalg.norm(cand - p[bad, None], axis=2), axis=1)
        out[bad] = cand[np.arange(len(k)), k]
    return out


class TriangleSet:
    """Triangles with their bounding spheres, for repeated closest-point queries.

    vertices : (v, 3) float; faces : (m, 3) int. Triangles are grouped by the size of their
    bounding spheres (quartiles of size, then the largest few, and split at every doubling of
    size), each group in a KD-tree over
    its centres; a query pairs points with every group's triangles whose sphere comes within
    the cap, in C (cKDTree.sparse_distance_matrix), then tests each pair exactly.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self.tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]
        m = len(self.tri)
        self.centre = self.tri.mean(axis=1) if m else np.zeros((0, 3))
        self.radius = (np.linalg.norm(self.tri - self.centre[:, None], axis=2).max(axis=1)
                       if m else np.zeros(0))
        self.groups = []                    # (triangle indices, largest radius, tree)
        if m:
            # quartiles of size, and no group whose largest sphere is over twice its smallest
            # (a query pairs a point with every centre within the group's largest radius, so
            # one large triangle in a group of small ones would pair it with all of them)
            quart = np.percentile(self.radius, [25, 50, 75, 95, 100])
            r_min = max(float(self.radius.min()), 1e-9)
            doubling = r_min * 2.0 ** np.arange(1, 1 + np.ceil(np.log2(quart[-1] / r_min)))
            edges = np.unique(np.r_[quart, doubling[doubling < quart[-1]]])
            lo = -np.inf
            for hi in edges:
                idx = np.nonzero((self.radius > lo) & (self.radius <= hi))[0]
                if len(idx):
                    self.groups.append((idx, float(hi), cKDTree(self.centre[idx])))
                lo = hi

    def _pairs(self, p: np.ndarray, cap: float) -> tuple[np.ndarray, np.ndarray]:
        """(point index, triangle index) pairs whose bounding sphere is within cap of the point."""
        tree = cKDTree(p)
        pts, tris = [], []
        for idx, r_max, t_tree in self.groups:
            sdm = tree.sparse_distance_matrix(t_tree, r_max + cap, output_type="ndarray")
            if len(sdm) == 0:
                continue
            t = idx[sdm["j"]]
            keep = sdm["v"] <= self.radius[t] + cap
            pts.append(sdm["i"][keep].astype(np.int64))
            tris.append(t[keep])
        if not pts:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(pts), np.concatenate(tris)

    def closest(self, points: np.ndarray, cap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest surface point of each point within `cap` metres.

        returns (distance (n,) float64, inf where nothing is within cap;
                 closest (n, 3) float64, NaN where nothing is within cap;
                 face (n,) int64 index of the nearest triangle, -1 where nothing is within cap)
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.full(len(p), np.inf)
        near_pt = np.full((len(p), 3), np.nan)
        face = np.full(len(p), -1, dtype=np.int64)
        if len(p) == 0 or len(self.tri) == 0:
            return out, near_pt, face
        pt, tr = self._pairs(p, cap)
        tri = self.tri
        for s in range(0, len(pt), PAIR_CHUNK):
            pp, tt = pt[s:s + PAIR_CHUNK], tr[s:s + PAIR_CHUNK]
            q = closest_on_triangles(p[pp], tri[tt, 0], tri[tt, 1], tri[tt, 2])
            d = np.linalg.norm(q - p[pp], axis=1)
            d = np.where(d <= cap, d, np.inf)
            # the best pair per point: sort by (point, distance) and keep each point's first
            order = np.lexsort((d, pp))
            first = np.ones(len(order), bool)
            first[1:] = pp[order][1:] != pp[order][:-1]
            sel = order[first]
            better = d[sel] < out[pp[sel]]
            out[pp[sel][better]] = d[sel][better]
            near_pt[pp[sel][better]] = q[sel][better]
            face[pp[sel][better]] = tt[sel][better]
        return out, near_pt, face


def distance_to_mesh(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                     cap: float) -> np.ndarray:
    """(n,) float64 distance from each point to the nearest triangle, exact where it is at
    most `cap` metres; inf where no triangle is that close.

    points : (n, 3) float; vertices : (v, 3) float; faces : (m, 3) int
    """
    return TriangleSet(vertices, faces).closest(points, cap)[0]


def segment_distances(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray,
                      q2: np.ndarray) -> np.ndarray:
    """(m,) metres: the closest distance between segments p1-q1 and p2-q2 (each (m, 3)),
    vectorized (Ericson, Real-Time Collision Detection, 5.1.9); a zero-length segment is a
    point."""
    eps = 1e-18
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = np.einsum("ij,ij->i", d1, d1), np.einsum("ij,ij->i", d2, d2)
    b, c, f = (np.einsum("ij,ij->i", d1, d2), np.einsum("ij,ij->i", d1, r),
               np.einsum("ij,ij->i", d2, r))
    a_ok, e_ok = a > eps, e > eps
    a_, e_ = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    s = np.where(denom > eps, np.clip((b * f - c * e) / np.where(denom > eps, denom, 1.0),
                                      0.0, 1.0), 0.0)
    s = np.where(e_ok, s, np.clip(-c / a_, 0.0, 1.0))
    t = np.where(e_ok, (b * s + f) / e_, 0.0)
    s = np.where(t < 0.0, np.clip(-c / a_, 0.0, 1.0),
                 np.where(t > 1.0, np.clip((b - c) / a_, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    s = np.where(a_ok, s, 0.0)
    t = np.where(a_ok, t, np.clip(f / e_, 0.0, 1.0) * e_ok)
    return np.linalg.norm(p1 + d1 * s[:, None] - p2 - d2 * t[:, None], axis=1)
