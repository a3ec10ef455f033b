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
    if not len(m.faces) and radius > 0:
        # trimesh drops every face of a capsule thinner than about 1e-5 m as degenerate:
        # such a capsule is made at unit radius and scaled
        m = trimesh.creation.capsule(height=max(length / radius - 2.0, 0.0), radius=1.0,
                                     count=[16, 16])
        m.vertices *= radius
    return m.vertices.astype(np.float32), m.faces.astype(np.uint32)
