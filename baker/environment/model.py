"""Environment data: the exportable meshes, the merged collision mesh and the sun."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import trimesh


@dataclass(frozen=True)
class EnvMesh:
    """One exportable piece of the environment, in the environment's local frame.

    vertices : (n, 3) float32, metres, local (world = Environment.origin + local; +Y up)
    faces    : (m, 3) uint32 indices into vertices
    normals  : (n, 3) float32 unit vertex normals, or None to let writers compute them
    color    : (4,) float, linear RGBA base colour
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    color: tuple[float, float, float, float] = (0.5, 0.5, 0.5, 1.0)
    roughness: float = 1.0
    metallic: float = 0.0


@dataclass(frozen=True)
class Sun:
    """A directional light.

    direction : (3,) float unit vector pointing FROM the scene TOWARD the sun
                (light travels along -direction).
    intensity : lux (glTF KHR_lights_punctual directional intensity)
    color     : linear RGB
    azimuth_rate : [rad/s] how fast the sun turns about +Y (counter-clockwise seen from above)
                during a bake, from a glTF light's extras `azimuth_deg_per_s`; 0: it stays put
    """

    direction: np.ndarray
    intensity: float = 3.0
    color: tuple[float, float, float] = (1.0, 0.95, 0.85)
    azimuth_rate: float = 0.0


@dataclass(frozen=True, eq=False)
class Environment:
    """Everything the simulation and the writers need to know about the world.

    meshes       : exportable pieces with materials, vertices in the local frame
    sun          : the directional light
    source       : file it was loaded from (for the report), or "" when built in code
    origin       : (3,) float64, metres, world position of the local frame's origin. The
                   simulation works in the local frame (world = origin + local), so levels far
                   from the world origin keep float32 and Embree precision; only inputs given in
                   world coordinates and outputs written as world positions add or subtract it
                   (see environment.load.choose_origin). Zeros for environments built in code.
    content_hash : sha256 of the merged local geometry (cache key for navigation surfaces: the
                   surface is in the local frame, so it does not depend on the origin)
    """

    meshes: tuple[EnvMesh, ...]
    sun: Sun
    source: str = ""
    name: str = "environment"
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        o = np.array(self.origin, dtype=np.float64).reshape(3)
        o.setflags(write=False)
        object.__setattr__(self, "origin", o)

    def to_local(self, p) -> np.ndarray:
        """World points (..., 3) -> local frame, float64."""
        return np.asarray(p, dtype=np.float64) - self.origin

    def to_world(self, p) -> np.ndarray:
        """Local points (..., 3) -> world, float64."""
        return np.asarray(p, dtype=np.float64) + self.origin

    @cached_property
    def mesh(self) -> trimesh.Trimesh:
        """All pieces merged into one triangle mesh in the local frame (for ray casts and the
        navigation build), each triangle once (distinct_triangles)."""
        offset = 0
        vs, fs = [], []
        for m in self.meshes:
            vs.append(np.asarray(m.vertices, dtype=np.float64))
            fs.append(np.asarray(m.faces, dtype=np.int64) + offset)
            offset += len(m.vertices)
        v = np.concatenate(vs)
        return trimesh.Trimesh(v, distinct_triangles(v, np.concatenate(fs)), process=False)

    @cached_property
    def content_hash(self) -> str:
        import hashlib

        h = hashlib.sha256()
        for m in self.meshes:
            h.update(np.ascontiguousarray(m.vertices, dtype=np.float32).tobytes())
            h.update(np.ascontiguousarray(m.faces, dtype=np.uint32).tobytes())
        return h.hexdigest()

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float: min and max corners, metres, local frame (add `origin` for world)."""
        return self.mesh.bounds

    @cached_property
    def rays(self):
        from baker.environment.rays import RayCaster

        return RayCaster(self.mesh)


def distinct_triangles(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """The faces `f` (T, 3) less the repeats of a triangle just before them in an order of
    their corners' hashes (the same three corners, bit for bit, wound the same way from any
    corner: a primitive or a mesh repeated in place); `f` itself when there are none. A column
    of the navigation build found each copy as a layer of its own, and a level of 200 copies of
    one box took 4 s and 0.9 GB to build (2000: past 300 s). A copy wound the other way is
    kept: a floor modelled once each way is walked whichever face the build meets first
    (navmesh facing). Each corner is hashed from its coordinates' bits, a triangle from its
    corners' hashes in its own order from the smallest; triangles whose hashes match are
    compared coordinate by coordinate, so a distinct triangle is never dropped."""
    if len(f) < 2:
        return f
    bits = np.ascontiguousarray(v, dtype=np.float64).view(np.uint64).reshape(-1, 3)
    point = _mixed(bits, _MIX[:3])
    first = np.argmin(point[f], axis=1)
    corners = np.take_along_axis(f, (first[:, None] + np.arange(3)) % 3, axis=1)  # same winding
    key = _mixed(point[corners], _MIX[3:])
    by_key = np.argsort(key, kind="stable")                   # equal keys: earliest first
    pair = np.nonzero(key[by_key[1:]] == key[by_key[:-1]])[0]
    if len(pair) == 0:
        return f
    later, earlier = by_key[pair + 1], by_key[pair]
    same = (v[corners[later]] == v[corners[earlier]]).all(axis=(1, 2))
    if not same.any():
        return f
    keep = np.ones(len(f), dtype=bool)
    keep[later[same]] = False
    return f[keep]


#: odd 64-bit multipliers of distinct_triangles' hashes: a corner's x, y, z, a triangle's
#: corners from the smallest
_MIX = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9,
                 0xD6E8FEB86659FD93, 0xFF51AFD7ED558CCD, 0xC4CEB9FE1A85EC53], dtype=np.uint64)


def _mixed(cols: np.ndarray, mix: np.ndarray) -> np.ndarray:
    """(n,) uint64 hash of (n, 3) uint64 columns: each column scrambled (splitmix64's
    finalizer: a float's bits, as 2.0's, have their low bits all zero), times mix[k], summed
    modulo 2^64 (element-wise uint64 arithmetic wraps)."""
    out = np.zeros(len(cols), dtype=np.uint64)
    for k in range(3):
        x = cols[:, k].copy()
        x ^= x >> np.uint64(30)
        x *= np.uint64(0xBF58476D1CE4E5B9)
        x ^= x >> np.uint64(27)
        x *= np.uint64(0x94D049BB133111EB)
        x ^= x >> np.uint64(31)
        x *= mix[k]
        out += x
    return out
