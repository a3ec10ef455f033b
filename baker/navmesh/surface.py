"""The navigation surface's data: plain numpy arrays, built by build.py (Recast's side), stored
by cache.py, queried through query.NavSurface (Detour's side). This module imports nothing of
baker: the data knows nothing of the queries.

Layout (Recast-like, but every sample is one ray hit at a column centre):
- The world's XZ plane is cut into a grid of square columns of side `cell_size`, starting at
  `origin` (x0, z0), `shape` = (nx, nz) columns. Column (ix, iz) has centre
  (x0 + (ix + 0.5) * cell, z0 + (iz + 0.5) * cell) and flat id col = ix * nz + iz.
- A column holds 0..k walkable samples (layers: a log top and the floor inside it). Samples are
  sorted by column id, then from top to bottom; `col_start` is the CSR index from column to
  samples: the samples of column c are col_start[c]:col_start[c + 1].
- `links[s, d]` is the sample reached from s by one step in direction DIRS[d], or -1.
  Directions 0..3 are the 4-neighbours (+X, +Z, -X, -Z), 4..7 the diagonals. Links are
  symmetric: links[links[s, d], OPPOSITE[d]] == s.
- A coarse graph (blocks of `coarse_factor` x `coarse_factor` columns, split into connected
  groups of samples) speeds up path finding; fine links give the exact answer.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

#: (dx, dz) column steps of the 8 link directions.
DIRS = np.array([(1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 1), (-1, -1), (1, -1)],
                dtype=np.int64)
#: OPPOSITE[d] is the direction that undoes DIRS[d].
OPPOSITE = np.array([2, 3, 0, 1, 6, 7, 4, 5], dtype=np.int64)
#: Format version of the arrays (bump when the layout or the build changes; part of cache keys).
FORMAT_VERSION = 7


@dataclass(frozen=True, eq=False)
class NavData:
    """A built navigation surface's data (Recast's dtNavMesh data, not its query object).
    Plain data: picklable, what navmesh.cache stores; query.NavSurface(data) answers queries.

    Arrays (N walkable samples, M coarse nodes, C = nx * nz columns, K components):
    positions     : (N, 3) float32, metres, world: the surface point at the column centre
    normals       : (N, 3) float32, unit surface normals (pointing up, y > 0)
    cells         : (N, 2) int32, (ix, iz) column of each sample
    col_start     : (C + 1,) int64, CSR column -> samples
    links         : (N, 8) int32, neighbour sample per direction (DIRS), -1 = no link
    component     : (N,) int32, connected component label, 0 = the largest
    clearance     : (N,) float32, metres: distance along the surface to the nearest edge of the
                    walkable area before erosion (inf when farther than the search limit)
    component_area: (K,) float64, m^2 of horizontal area per component
    coarse_of     : (N,) int32, coarse node of each sample
    coarse_rep    : (M,) int32, representative sample of each coarse node
    coarse_indptr : (M + 1,) int64 and coarse_indices (E,) int32: coarse graph (CSR, symmetric)
    Scalars: origin (x0, z0) metres, shape (nx, nz), cell_size metres, coarse_factor columns,
    agent parameters (metres / radians) the surface was built for.
    """

    positions: np.ndarray
    normals: np.ndarray
    cells: np.ndarray
    col_start: np.ndarray
    links: np.ndarray
    component: np.ndarray
    clearance: np.ndarray
    component_area: np.ndarray
    coarse_of: np.ndarray
    coarse_rep: np.ndarray
    coarse_indptr: np.ndarray
    coarse_indices: np.ndarray
    origin: tuple[float, float]
    shape: tuple[int, int]
    cell_size: float
    coarse_factor: int
    agent_radius: float
    agent_height: float
    step_height: float
    max_slope: float

    @property
    def n_samples(self) -> int:
        return int(len(self.positions))

    @property
    def n_components(self) -> int:
        return int(len(self.component_area))

    @property
    def walkable_area(self) -> float:
        """Horizontal walkable area, m^2 (samples x cell^2)."""
        return float(self.n_samples * self.cell_size ** 2)

    def stats(self) -> dict:
        """Summary for reports (plain JSON types)."""
        return {
            "samples": self.n_samples,
            "walkable_area_m2": round(self.walkable_area, 4),
            "components": self.n_components,
            "largest_component_m2": round(float(self.component_area[0]), 4)
            if self.n_components else 0.0,
            "grid": [int(self.shape[0]), int(self.shape[1])],
            "cell_size": self.cell_size,
            "agent": {"radius": self.agent_radius, "height": self.agent_height,
                      "step_height": self.step_height, "max_slope": self.max_slope},
            "format_version": FORMAT_VERSION,
        }

    def arrays(self) -> dict:
        """Every field as a dict of numpy arrays / scalars (for .npz saving)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class PathResult:
    """A path on the surface.

    points   : (k, 3) float64, metres, world; start first; every point on the surface
    complete : False when the goal is unreachable: points end at the closest reachable point
    """

    points: np.ndarray
    complete: bool

    @property
    def length(self) -> float:
        if len(self.points) < 2:
            return 0.0
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())
