"""Batched ray queries on the environment (Embree through trimesh/embreex).

Every query takes arrays of rays and casts them in one call. Faces are treated as two-sided:
face winding never matters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from baker.geometry.transforms import normalize


@dataclass(frozen=True)
class Hits:
    """Result of a batch of first-hit ray casts.

    hit      : (n,) bool
    distance : (n,) float, metres along the (unit) ray; inf where no hit
    points   : (n, 3) float, world; NaN where no hit
    normals  : (n, 3) float, unit face normals flipped to face the ray origin; NaN where no hit
    faces    : (n,) int, face index; -1 where no hit
    """

    hit: np.ndarray
    distance: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    faces: np.ndarray


class RayCaster:
    """First-hit and occlusion queries against one triangle mesh."""

    def __init__(self, mesh: trimesh.Trimesh):
        self.mesh = mesh
        self._face_normals = np.asarray(mesh.face_normals, dtype=np.float64)
        try:
            from trimesh.ray.ray_pyembree import RayMeshIntersector

            self._intersector = RayMeshIntersector(mesh, scale_to_box=False)
        except Exception:  # pragma: no cover - embreex missing: fall back, slower
            self._intersector = trimesh.ray.ray_triangle.RayMeshIntersector(mesh)

    def first_hit(self, origins: np.ndarray, directions: np.ndarray,
                  max_distance: float | np.ndarray = np.inf) -> Hits:
        """Nearest hit along each ray.

        origins    : (n, 3) float, world
        directions : (n, 3) float, normalized internally
        max_distance : scalar or (n,), hits further than this are dropped
        """
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        directions = normalize(np.asarray(directions, dtype=np.float64).reshape(-1, 3))
        n = len(origins)
        hit = np.zeros(n, dtype=bool)
        dist = np.full(n, np.inf)
        pts = np.full((n, 3), np.nan)
        nrm = np.full((n, 3), np.nan)
        faces = np.full(n, -1, dtype=np.int64)
        if n == 0:
            return Hits(hit, dist, pts, nrm, faces)
        loc, ray_idx, tri_idx = self._intersector.intersects_location(
            origins, directions, multiple_hits=False)
        if len(ray_idx):
            d = np.einsum("ij,ij->i", loc - origins[ray_idx], directions[ray_idx])
            keep = d <= np.broadcast_to(max_distance, (n,))[ray_idx]
            r, t, l, d = ray_idx[keep], tri_idx[keep], loc[keep], d[keep]
            hit[r] = True
            dist[r] = d
            pts[r] = l
            faces[r] = t
            fn = self._face_normals[t]
            flip = np.einsum("ij,ij->i", fn, directions[r]) > 0
            fn[flip] *= -1.0
            nrm[r] = fn
        return Hits(hit, dist, pts, nrm, faces)

    def cast_down(self, points: np.ndarray, height: float | np.ndarray,
                  max_distance: float | np.ndarray = np.inf) -> Hits:
        """Cast straight down from `height` metres above each point.

        points : (n, 3) float, world. Rays start at points + height * UP.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        o = points.copy()
        o[:, 1] += height
        d = np.zeros_like(o)
        d[:, 1] = -1.0
        return self.first_hit(o, d, max_distance)

    def occluded(self, origins: np.ndarray, directions: np.ndarray,
                 max_distance: float | np.ndarray = np.inf) -> np.ndarray:
        """(n,) bool: True where something blocks the ray within max_distance."""
        return self.first_hit(origins, directions, max_distance).hit
