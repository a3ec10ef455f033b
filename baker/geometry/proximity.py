"""Exact point-to-triangle-mesh distances within a cap.

Used to judge contacts from the files alone: a foot is "on the ground" when its distance to the
nearest surface (any direction, walls included) is small. The nearest triangle of each point
comes from libigl's AABB tree (C++, built once per mesh); only distances up to a cap are kept.
"""

from __future__ import annotations

import numpy as np


class TriangleSet:
    """Triangles in an axis-aligned bounding-box tree, for repeated closest-point queries.

    vertices : (v, 3) float; faces : (m, 3) int. The tree (libigl's `AABB`) is built on the
    first query; each query finds every point's nearest triangle exactly (squared distances in
    float64), however far, and keeps those within the cap.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self.vertices = np.ascontiguousarray(vertices, dtype=np.float64).reshape(-1, 3)
        self.faces = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
        self._tree = None

    def _built(self):
        if self._tree is None:
            import igl

            self._tree = igl.AABB()
            self._tree.init(self.vertices, self.faces)
        return self._tree

    def closest(self, points: np.ndarray, cap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest surface point of each point within `cap` metres.

        returns (distance (n,) float64, inf where nothing is within cap;
                 closest (n, 3) float64, NaN where nothing is within cap;
                 face (n,) int64 index of the nearest triangle, -1 where nothing is within cap)
        """
        p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.full(len(p), np.inf)
        near_pt = np.full((len(p), 3), np.nan)
        face = np.full(len(p), -1, dtype=np.int64)
        if len(p) == 0 or len(self.faces) == 0:
            return out, near_pt, face
        d2, tri, q = self._built().squared_distance(self.vertices, self.faces, p)
        d = np.sqrt(d2)
        within = d <= cap
        out[within] = d[within]
        near_pt[within] = q[within]
        face[within] = tri[within]
        return out, near_pt, face


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
