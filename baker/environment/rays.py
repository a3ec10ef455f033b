"""Batched ray queries on the environment, straight on Embree (embreex).

Every query takes arrays of rays and casts them in one call. Faces are two-sided: winding never
matters. The Embree scene is float32, so it is re-centred on the mesh's bounding box (origins
are shifted in float64 before rounding); that keeps millimetre precision on kilometre levels.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import trimesh

from baker.geometry.transforms import normalize
from baker.parallel import thread_count, thread_map

log = logging.getLogger(__name__)

#: straight down (RayCaster.cast_columns), in float64 and as Embree's one shared direction
_DOWN = np.array([[0.0, -1.0, 0.0]])
_DOWN32 = _DOWN.astype(np.float32)
#: the six axis directions cast by RayCaster.inside
_AXES6 = np.array([[0, 1, 0], [0, -1, 0], [1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 0, -1]], float)
#: rays per Embree call (bounds the float32 staging buffers)
CHUNK_RAYS = 1 << 20
#: a batch is cast on several threads only when each gets at least this many rays (a thread's
#: start costs about as much as casting a few hundred rays)
THREAD_MIN_RAYS = 16384
#: at most this many threads cast one batch
MAX_THREADS = 8
#: a batch of at most this many rays (the run stage's per-step probes) is cast in one Embree
#: call without the staging and the masks of large batches, whose cost is many times the cast's
SMALL_RAYS = 64


def _threads() -> int:
    """Threads a large batch of rays is cast on: parallel.thread_count(), at most
    MAX_THREADS."""
    return min(thread_count(), MAX_THREADS)


def _in_parts(n: int, cast) -> None:
    """cast(start, stop) over rays 0..n-1: in one call, or, for a large batch, in contiguous
    parts each on its own thread (Embree's query runs with the GIL released; each part writes
    its own rows: the same bits as one thread)."""
    parts = min(_threads(), n // THREAD_MIN_RAYS) if n >= 2 * THREAD_MIN_RAYS else 1
    if parts <= 1:
        cast(0, n)
        return
    edges = np.linspace(0, n, parts + 1).astype(np.int64).tolist()
    thread_map(lambda k: cast(edges[k], edges[k + 1]), range(parts), threads=parts)


def _store(r: dict, t: np.ndarray, prim: np.ndarray, a: int, b: int) -> np.ndarray:
    """Write Embree's answer r for rays a..b into prim and (at the hits) t; returns the hits
    (b - a,) bool."""
    p = r["primID"]
    hit = p >= 0
    prim[a:b] = p
    t[a:b][hit] = r["tfar"][hit]
    return hit


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
    """First-hit and occlusion queries against one triangle mesh.

    face_normals : (m, 3) float64 unit normals as wound (zero for degenerate faces)
    shift        : (3,) float64, the scene's centre (subtracted before float32 rounding)
    """

    def __init__(self, mesh: trimesh.Trimesh):
        self.mesh = mesh
        v = np.asarray(mesh.vertices, dtype=np.float64)
        f = np.asarray(mesh.faces, dtype=np.int64)
        self.vertices, self.faces = v, f
        self.shift = (v.min(axis=0) + v.max(axis=0)) * 0.5 if len(v) else np.zeros(3)
        fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]) if len(f) else np.zeros((0, 3))
        ln = np.linalg.norm(fn, axis=1)
        fn[ln > 0] /= ln[ln > 0, None]
        self.face_normals = fn
        self._scene = None
        try:
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh

            if len(f):
                self._scene = rtcore_scene.EmbreeScene()
                TriangleMesh(scene=self._scene, vertices=(v - self.shift).astype(np.float32),
                             indices=f.astype(np.int32))
        except ImportError:  # pragma: no cover - embreex missing: trimesh's slower casts
            log.warning("embreex unavailable: ray casts fall back to trimesh")
            self._fallback = trimesh.ray.ray_triangle.RayMeshIntersector(mesh)

    def cast(self, origins: np.ndarray, directions: np.ndarray,
             max_distance: float | np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The raw batch query.

        origins, directions : (n, 3) float (directions unit length)
        max_distance        : scalar, (n,) or None (unbounded)
        returns (t (n,) float64 with inf on a miss, prim (n,) int32 with -1 on a miss)
        """
        return self._run(origins, directions, max_distance, None)

    def cast_uv(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, ...]:
        """cast() (unbounded) with the hits' barycentric coordinates: (t, prim, uv (n, 2)
        float64), the hit point being (1 - u - v) v0 + u v1 + v v2 of face prim (0 on a miss)."""
        uv = np.zeros((len(np.asarray(origins).reshape(-1, 3)), 2))
        t, prim = self._run(origins, directions, None, uv)
        return t, prim, uv

    def _run(self, origins, directions, max_distance, uv):
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        n = len(origins)
        if 0 < n <= SMALL_RAYS and self._scene is not None:
            return self._small(origins, directions, max_distance, uv)
        t = np.full(n, np.inf)
        prim = np.full(n, -1, dtype=np.int32)
        if n == 0 or len(self.faces) == 0:
            return t, prim
        if self._scene is None:  # pragma: no cover
            t, prim = self._cast_fallback(origins, directions, max_distance)
            if uv is not None and np.any(prim >= 0):
                h = prim >= 0
                bary = trimesh.triangles.points_to_barycentric(
                    self.vertices[self.faces[prim[h]]], origins[h] + t[h, None] * directions[h])
                uv[h] = bary[:, 1:]
            return t, prim
        dist = None if max_distance is None else np.broadcast_to(
            np.asarray(max_distance, dtype=np.float64), (n,))
        _in_parts(n, lambda a, b: self._embree(origins, directions, dist, uv, t, prim, a, b))
        return t, prim

    def _small(self, origins, directions, max_distance, uv):
        """_run for a batch of 1..SMALL_RAYS rays on Embree: one _query, without the staging of
        large batches (the same bits)."""
        dist = None if max_distance is None else np.broadcast_to(
            np.asarray(max_distance, dtype=np.float64), (len(origins),))
        r = self._query(origins, directions, dist)
        prim = r["primID"]
        hit = prim >= 0
        t = np.where(hit, r["tfar"].astype(np.float64), np.inf)
        if uv is not None:
            uv[:, 0] = np.where(hit, r["u"], 0.0)
            uv[:, 1] = np.where(hit, r["v"], 0.0)
        return t, prim.astype(np.int32, copy=False)

    def _query(self, origins, directions, dist) -> dict:
        """Embree's answer (primID, tfar, u, v, ...) for rays origins, directions (n, 3) float64
        and dist (n,) float64 or None (unbounded): the origins shifted in float64, then rounded
        to float32, the distances capped at 3e38."""
        o = np.empty(origins.shape, np.float32)
        np.subtract(origins, self.shift, out=o, casting="same_kind")
        d = np.ascontiguousarray(directions, dtype=np.float32)
        if dist is None:
            return self._scene.run(o, d, output=1)
        return self._scene.run(o, d, dists=np.minimum(dist, 3e38).astype(np.float32), output=1)

    def _embree(self, origins, directions, dist, uv, t, prim, start: int, stop: int) -> None:
        """Cast rays start..stop on Embree, CHUNK_RAYS at a time, into t, prim (and uv)."""
        for a in range(start, stop, CHUNK_RAYS):
            b = min(stop, a + CHUNK_RAYS)
            r = self._query(origins[a:b], directions[a:b], None if dist is None else dist[a:b])
            hit = _store(r, t, prim, a, b)
            if uv is not None:
                uv[a:b, 0] = np.where(hit, r["u"], 0.0)
                uv[a:b, 1] = np.where(hit, r["v"], 0.0)

    def cast_columns(self, x: np.ndarray, y: np.ndarray, z: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """cast() of unbounded rays straight down from (x, y, z) (each (n,) float64), the same
        bits, without the (n, 3) origin and direction arrays: the origins are shifted and
        rounded to float32 coordinate by coordinate, and every ray shares one direction (millions
        of rays over a grid's columns: the reference the navigation build's rasterized columns
        are tested against)."""
        n = len(x)
        if self._scene is None or n <= SMALL_RAYS:
            o = np.stack([x, y, z], axis=1)
            return self.cast(o, np.broadcast_to(_DOWN, o.shape))
        t = np.full(n, np.inf)
        prim = np.full(n, -1, dtype=np.int32)

        def part(a: int, b: int) -> None:
            for c0 in range(a, b, CHUNK_RAYS):
                c1 = min(b, c0 + CHUNK_RAYS)
                o = np.empty((c1 - c0, 3), np.float32)
                for k, v in enumerate((x, y, z)):
                    np.subtract(v[c0:c1], self.shift[k], out=o[:, k], casting="same_kind")
                _store(self._scene.run(o, _DOWN32, output=1), t, prim, c0, c1)

        _in_parts(n, part)
        return t, prim

    def _cast_fallback(self, origins, directions, max_distance):  # pragma: no cover
        n = len(origins)
        t = np.full(n, np.inf)
        prim = np.full(n, -1, dtype=np.int32)
        loc, ray_idx, tri_idx = self._fallback.intersects_location(origins, directions,
                                                                   multiple_hits=False)
        if len(ray_idx):
            d = np.einsum("ij,ij->i", loc - origins[ray_idx], directions[ray_idx])
            lim = np.inf if max_distance is None else np.broadcast_to(max_distance, (n,))[ray_idx]
            keep = d <= lim
            t[ray_idx[keep]] = d[keep]
            prim[ray_idx[keep]] = tri_idx[keep]
        return t, prim

    def first_hit(self, origins: np.ndarray, directions: np.ndarray,
                  max_distance: float | np.ndarray = np.inf) -> Hits:
        """Nearest hit along each ray.

        origins    : (n, 3) float, world
        directions : (n, 3) float, normalized internally
        max_distance : scalar or (n,), hits further than this are dropped
        """
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        directions = normalize(np.asarray(directions, dtype=np.float64).reshape(-1, 3))
        t, prim = self.cast(origins, directions, max_distance)
        hit = prim >= 0
        if hit.all():       # every ray hit (most batches): the same values without the masks
            fn = self.face_normals[prim]
            fn[np.einsum("ij,ij->i", fn, directions) > 0] *= -1.0
            return Hits(hit, t, origins + t[:, None] * directions, fn, prim.astype(np.int64))
        n = len(origins)
        pts = np.full((n, 3), np.nan)
        nrm = np.full((n, 3), np.nan)
        pts[hit] = origins[hit] + t[hit, None] * directions[hit]
        fn = self.face_normals[prim[hit]]
        flip = np.einsum("ij,ij->i", fn, directions[hit]) > 0
        fn[flip] *= -1.0
        nrm[hit] = fn
        return Hits(hit, t, pts, nrm, np.where(hit, prim, -1).astype(np.int64))

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

    @cached_property
    def triangles(self):
        """geometry.proximity.TriangleSet of the mesh (closest-point queries)."""
        from baker.geometry.proximity import TriangleSet

        return TriangleSet(self.vertices, self.faces)

    def closest(self, points: np.ndarray, cap: float):
        """(distance, closest point, face) of each point's nearest surface within `cap` metres
        (TriangleSet.closest)."""
        return self.triangles.closest(points, cap)

    def inside(self, points: np.ndarray) -> np.ndarray:
        """(n,) bool: each point is inside a solid.

        points : (n, 3) float, metres, world. Six axis rays per point, in two batches (the ray
        straight up first, the other five only where it meets something); each
        first hit votes "back" when the ray leaves through the face's back (its normal, as
        wound, points along the ray) and "front" otherwise. A point is inside when back votes
        outnumber front votes, also outweigh them with each vote weighted by how squarely its
        ray meets the face (|cos|: a ray that grazes rough ground far away, through a seam
        between overlapping patches, says little about which side of it the point is), and
        the nearest hit is a back face (a foot in the open over the ground, under a one-sided
        leaf, with some face metres away seen from behind, is not inside: the ground it sees
        first is a front), and something is straight overhead (+Y): a point inside a closed
        solid sees its top from below, and one under a one-sided ground its underside, so a
        point under the open sky is in the open, however many leaves or slopes its sideways
        rays meet from behind (a body between two overlapping one-sided leaves, the upper
        leaf's edge beside it). On a closed, consistently outward-wound mesh every first hit from
        inside is a back face, so this is exact there; the majority vote tolerates flipped
        faces away from the point and open meshes (a one-sided ground plane: a point below it sees its back from
        below and nothing else, so it counts as inside; a one-sided deck overhead with a floor
        below is one vote each, so not inside). Limitation: it trusts the winding. A mesh wound
        inward throughout, or an object whose faces are mostly flipped, reads inside-out.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.zeros(len(p), dtype=bool)
        if len(p) == 0:
            return out
        # the ray straight up first: the other five only where it meets something
        t_up, prim_up = self.cast(p, np.broadcast_to(_AXES6[0], p.shape))
        roofed = np.nonzero(prim_up >= 0)[0]
        n = len(roofed)
        if n == 0:
            return out
        t5, prim5 = self.cast(np.repeat(p[roofed], 5, axis=0), np.tile(_AXES6[1:], (n, 1)))
        t = np.column_stack([t_up[roofed], t5.reshape(n, 5)])
        prim = np.column_stack([prim_up[roofed], prim5.reshape(n, 5)])
        hit = prim >= 0
        vote = np.zeros((n, 6))
        vote[hit] = np.einsum("ij,ij->i", self.face_normals[prim[hit]],
                              np.broadcast_to(_AXES6, (n, 6, 3))[hit])
        nearest = vote[np.arange(n), np.argmin(t, axis=1)]
        out[roofed] = ((np.count_nonzero(vote > 0, axis=1) > np.count_nonzero(vote < 0, axis=1))
                       & (vote.sum(axis=1) > 0.0) & (nearest > 0.0))
        return out

    def occluded(self, origins: np.ndarray, directions: np.ndarray,
                 max_distance: float | np.ndarray = np.inf) -> np.ndarray:
        """(n,) bool: True where something blocks the ray within max_distance. directions:
        (n, 3) (or anything that broadcasts to it), or one (3,) direction for every ray
        (normalized once)."""
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(directions, dtype=np.float64)
        if d.shape == (3,):
            one = normalize(d)
            d = np.empty_like(origins)
            d[...] = one
        else:
            d = normalize(np.broadcast_to(d, origins.shape))
        return self.cast(origins, d, max_distance)[1] >= 0
