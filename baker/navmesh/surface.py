"""The navigation surface data: plain numpy arrays, built by build.py, queried by query.py.

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

from dataclasses import dataclass, field, fields

import numpy as np

#: (dx, dz) column steps of the 8 link directions.
DIRS = np.array([(1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 1), (-1, -1), (1, -1)],
                dtype=np.int64)
#: OPPOSITE[d] is the direction that undoes DIRS[d].
OPPOSITE = np.array([2, 3, 0, 1, 6, 7, 4, 5], dtype=np.int64)
#: Format version of the arrays (bump when the layout or the build changes; part of cache keys).
FORMAT_VERSION = 3


@dataclass(frozen=True, eq=False)
class NavSurface:
    """A built navigation surface. Plain data: picklable, saved to .npz by navmesh.cache.

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
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    # ------------------------------------------------------------------ plain properties
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

    @property
    def link_indptr(self) -> np.ndarray:
        """CSR view of the links: (N + 1,) int64 (see link_indices)."""
        return self._csr()[0]

    @property
    def link_indices(self) -> np.ndarray:
        """CSR view of the links: (L,) int32 neighbour samples, rows in sample order."""
        return self._csr()[1]

    def _csr(self):
        c = self._cache.get("csr")
        if c is None:
            m = self.links >= 0
            indptr = np.zeros(len(self.links) + 1, dtype=np.int64)
            np.cumsum(m.sum(axis=1), out=indptr[1:])
            c = (indptr, self.links[m].astype(np.int32))
            self._cache["csr"] = c
        return c

    def prepare(self) -> "NavSurface":
        """Build the lazy query tables now (coarse-graph lists, members, block index) instead
        of on the first query (about 0.1-0.3 s on a few million samples). Returns self."""
        from baker.navmesh import query
        query._coarse_lists(self)
        query._members(self)
        query._coarse_index(self)
        return self

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
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "_cache"}

    def __getstate__(self):
        return self.arrays()

    def __setstate__(self, state):
        for k, v in state.items():
            object.__setattr__(self, k, v)
        object.__setattr__(self, "_cache", {})

    # ------------------------------------------------------------------ queries (query.py)
    def nearest(self, p, max_dist: float = np.inf) -> np.ndarray | None:
        """(3,) closest walkable surface point to p (within max_dist, 3D), or None."""
        from baker.navmesh import query
        return query.nearest(self, p, max_dist)

    def random_point_near(self, p, radius: float, rng: np.random.Generator) -> np.ndarray | None:
        """(3,) random walkable point within `radius` (3D) of p, reachable from p, uniform by
        surface area; None when there is none."""
        from baker.navmesh import query
        return query.random_point_near(self, p, radius, rng)

    def find_path(self, a, b) -> "PathResult":
        """Shortest-ish smoothed path from a to b on the surface (see query.find_path)."""
        from baker.navmesh import query
        return query.find_path(self, a, b)

    def is_walkable(self, points, tol: float | None = None) -> np.ndarray:
        """(n,) bool: points within `tol` (vertically) of the walkable surface."""
        from baker.navmesh import query
        return query.is_walkable(self, points, tol)

    def component_of(self, p) -> int:
        """Component label of the sample nearest p, -1 when the surface is empty."""
        from baker.navmesh import query
        return query.component_of(self, p)

    def surface_height(self, points, tol: float = np.inf) -> np.ndarray:
        """(n,) surface height under each point (the layer closest in height), NaN if none."""
        from baker.navmesh import query
        return query.surface_height(self, points, tol)

    def layer_height(self, x: float, y: float, z: float, tol: float) -> float:
        """Height of the walkable layer in the column of (x, z) closest to y (within tol, else
        NaN): a scalar surface_height for per-step use."""
        from baker.navmesh import query
        return query.layer_height(self, x, y, z, tol)

    def resample_path(self, points, spacing: float | None = None) -> np.ndarray:
        """(m, 3) points along a path every `spacing` m, heights on the walked surface."""
        from baker.navmesh import query
        return query.resample_path(self, points, spacing)

    def segment_visible(self, a, b) -> bool:
        """True when the straight segment a-b stays on linked walkable samples of one layer."""
        from baker.navmesh import query
        return query.segment_visible(self, a, b)


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
