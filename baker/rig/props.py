"""Meshes for scene objects the creature interacts with (prey capsules)."""

from __future__ import annotations

import numpy as np
import trimesh


def capsule_mesh(length: float, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """A capsule along +Z centred on the origin.

    length : metres, tip to tip (at least 2 * radius), radius : metres
    returns (vertices (n, 3) float32, faces (m, 3) uint32)
    """
    m = trimesh.creation.capsule(height=max(length - 2.0 * radius, 0.0), radius=radius,
                                 count=[16, 16])
    return m.vertices.astype(np.float32), m.faces.astype(np.uint32)
