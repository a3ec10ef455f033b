"""query._astar over the coarse graph, compiled (numba): the same path, node for node.

query._astar pops its heap's least (f, g, node) tuple, f = g + the straight distance to the
goal, and relaxes the node's edges in CSR order with Euclidean lengths; a node is closed once
expanded. Which entry a binary heap holds where depends on how it is built, but the entry it
pops never does: always the lexicographic least (f, g, node) (two equal entries are the same
entry), so this heap pops the same sequence whatever its layout. The lengths and distances are
_edge_length's arithmetic (x ** 2 is x * x, correctly rounded either way), so every f and g
has the same bits.

The kernel writes its path into an array it is given and returns nothing: it is called on the
main thread once compiled (parallel.compiled_call). Imported on the first coarse path (the
CLI's option errors come before numba is imported).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from baker.parallel import compiled_call


def coarse_astar(indptr: np.ndarray, indices: np.ndarray, pos: np.ndarray, start: int,
                 goal: int) -> list[int] | None:
    """query._coarse_astar's node path start..goal over the CSR graph (indptr (N + 1,) int64,
    indices (L,) int64, pos (N, 3) float64 representatives), or None when goal is
    unreachable."""
    out = np.empty(len(pos) + 1, dtype=np.int64)        # out[0]: the path's length
    compiled_call(_astar, indptr, indices, pos, int(start), int(goal), out)
    n = int(out[0])
    return None if n == 0 else out[1:n + 1].tolist()


@njit(cache=True, nogil=True)
def _less(f, g, node, i, j):
    """Heap entry i before entry j: (f, g, node) compared as Python compares tuples."""
    if f[i] != f[j]:
        return f[i] < f[j]
    if g[i] != g[j]:
        return g[i] < g[j]
    return node[i] < node[j]


@njit(cache=True, nogil=True)
def _swap(f, g, node, i, j):
    """Exchange heap entries i and j."""
    f[i], f[j] = f[j], f[i]
    g[i], g[j] = g[j], g[i]
    node[i], node[j] = node[j], node[i]


@njit(cache=True, nogil=True)
def _push(f, g, node, size, fv, gv, nv):
    """Add (fv, gv, nv) to the heap of `size` entries; returns the new size."""
    i = size
    f[i], g[i], node[i] = fv, gv, nv
    while i > 0:
        p = (i - 1) // 2
        if not _less(f, g, node, i, p):
            break
        _swap(f, g, node, i, p)
        i = p
    return size + 1


@njit(cache=True, nogil=True)
def _pop(f, g, node, size):
    """Move the least entry to index size - 1 (then read it there); returns the new size."""
    last = size - 1
    _swap(f, g, node, 0, last)
    i = 0
    while True:
        c = 2 * i + 1
        if c >= last:
            break
        if c + 1 < last and _less(f, g, node, c + 1, c):
            c += 1
        if not _less(f, g, node, c, i):
            break
        _swap(f, g, node, i, c)
        i = c
    return last


@njit(cache=True, nogil=True)
def _astar(indptr, indices, pos, start, goal, out):
    n = pos.shape[0]
    gx, gy, gz = pos[goal, 0], pos[goal, 1], pos[goal, 2]
    best = np.full(n, math.inf)
    parent = np.full(n, -1, dtype=np.int64)
    cap = indices.shape[0] + 1                     # one push per relaxation, and the start
    f = np.empty(cap)
    g = np.empty(cap)
    node = np.empty(cap, dtype=np.int64)
    closed = -math.inf
    best[start] = 0.0
    ux, uy, uz = pos[start, 0], pos[start, 1], pos[start, 2]
    size = _push(f, g, node, 0, math.sqrt((ux - gx) ** 2 + (uy - gy) ** 2 + (uz - gz) ** 2),
                 0.0, start)
    out[0] = 0
    while size > 0:
        size = _pop(f, g, node, size)
        gu, u = g[size], node[size]
        if u == goal:
            k = 0
            v = u
            while v >= 0:                          # goal back to start, then reversed
                out[1 + k] = v
                k += 1
                v = parent[v]
            out[1:1 + k] = out[1:1 + k][::-1].copy()
            out[0] = k
            return
        if best[u] == closed:
            continue
        best[u] = closed
        px, py, pz = pos[u, 0], pos[u, 1], pos[u, 2]
        for e in range(indptr[u], indptr[u + 1]):
            v = indices[e]
            qx, qy, qz = pos[v, 0], pos[v, 1], pos[v, 2]
            ng = gu + math.sqrt((qx - px) ** 2 + (qy - py) ** 2 + (qz - pz) ** 2)
            if ng < best[v]:
                best[v] = ng
                parent[v] = u
                size = _push(f, g, node, size,
                             ng + math.sqrt((qx - gx) ** 2 + (qy - gy) ** 2 + (qz - gz) ** 2),
                             ng, v)
