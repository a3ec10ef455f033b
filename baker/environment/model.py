"""Environment data: the exportable meshes, the merged collision mesh and the sun."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import trimesh


@dataclass(frozen=True)
class EnvMesh:
    """One exportable piece of the environment, already in world space.

    vertices : (n, 3) float32, metres, world (+Y up)
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
    """

    direction: np.ndarray
    intensity: float = 3.0
    color: tuple[float, float, float] = (1.0, 0.95, 0.85)


@dataclass(frozen=True, eq=False)
class Environment:
    """Everything the simulation and the writers need to know about the world.

    meshes       : exportable pieces with materials
    sun          : the directional light
    source       : file it was loaded from (for the report), or "" when built in code
    content_hash : sha256 of the merged geometry (cache key for navigation surfaces)
    """

    meshes: tuple[EnvMesh, ...]
    sun: Sun
    source: str = ""
    name: str = "environment"

    @cached_property
    def mesh(self) -> trimesh.Trimesh:
        """All pieces merged into one world-space triangle mesh (for ray casts)."""
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
        """(2, 3) float: min and max corners, metres."""
        return self.mesh.bounds

    @cached_property
    def rays(self):
        from baker.environment.rays import RayCaster

        return RayCaster(self.mesh)
