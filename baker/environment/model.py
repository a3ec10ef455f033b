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
        """All pieces merged into one triangle mesh in the local frame (for ray casts)."""
        offset = 0
        vs, fs = [], []
        for m in self.meshes:
            vs.append(np.asarray(m.vertices, dtype=np.float64))
            fs.append(np.asarray(m.faces, dtype=np.int64) + offset)
            offset += len(m.vertices)
        return trimesh.Trimesh(np.concatenate(vs), np.concatenate(fs), process=False)

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
