"""query._locate compiled (numba): per point, the sample of its column whose tangent plane is
closest in height, with the same choice and the same bits as query._locate_few's Python.

Each point tries its column's samples top to bottom and keeps the first of the closest within
`tol` (a strict `<`), the plane's height being _plane_y's arithmetic (float32 positions and
normals widen exactly to float64). A point found in no column is nudged 1e-6 cells into the
neighbouring columns, in query._NUDGES' order, and takes the first nudge that finds one (a
point on a cell border: path corners often are).

The kernel writes into arrays it is given and returns nothing: it is called on the main thread
once compiled (parallel.compiled_call). Imported on the first location query (the CLI's option
errors come before numba is imported).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from baker.parallel import compiled_call


def locate(cols: np.ndarray, pos: np.ndarray, nrm: np.ndarray, grid: np.ndarray,
           points: np.ndarray, tol: float, retry: bool, nudges: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """(sample (n,) int64, -1 for none; its plane's height (n,) float64, NaN for none) of
    every point (n, 3) float64, on the grid's arrays (query.grid_arrays) with `nudges` (k, 2)
    in cells tried for a point found nowhere when `retry`."""
    n = len(points)
    best = np.empty(n, dtype=np.int64)
    height = np.empty(n, dtype=np.float64)
    compiled_call(_locate_points, cols, pos, nrm, grid, points, float(tol), bool(retry),
                  nudges, best, height)
    return best, height


@njit(cache=True, nogil=True)
def _locate_points(cols, pos, nrm, grid, points, tol, retry, nudges, best, height):
    eps = 1e-6 * grid[2]
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        k, h = _locate_one(cols, pos, nrm, grid, x, y, z, tol)
        if k < 0 and retry:
            for j in range(nudges.shape[0]):
                k, h = _locate_one(cols, pos, nrm, grid, x + nudges[j, 0] * eps, y + 0.0,
                                   z + nudges[j, 1] * eps, tol)
                if k >= 0:
                    break
        best[i] = k
        height[i] = h


@njit(cache=True, nogil=True)
def _locate_one(cols, pos, nrm, grid, x, y, z, tol):
    """query._locate_one: (sample, plane height), or (-1, NaN)."""
    if not (math.isfinite(x) and math.isfinite(z)):
        return -1, math.nan
    # the column as floats: the same test as Python's integers, with no overflow
    fx = np.floor((x - grid[0]) / grid[2])
    fz = np.floor((z - grid[1]) / grid[2])
    if not (0.0 <= fx < grid[3] and 0.0 <= fz < grid[4]):
        return -1, math.nan
    col = int(fx) * int(grid[4]) + int(fz)
    best, besth, bestd = -1, math.nan, math.inf
    for k in range(cols[col], cols[col + 1]):
        px, py, pz = float(pos[k, 0]), float(pos[k, 1]), float(pos[k, 2])
        h = py - (float(nrm[k, 0]) * (x - px) + float(nrm[k, 2]) * (z - pz)) / float(nrm[k, 1])
        d = abs(h - y)
        if d < bestd and d <= tol:
            best, besth, bestd = k, h, d
    return best, besth
