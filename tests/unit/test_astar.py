"""The navigation query's A* (navmesh.query._astar): the same node paths as the textbook form
with a closed set, ties included (find_path's results must not move by a bit)."""

from __future__ import annotations

import heapq
import math

import numpy as np
import pytest

from baker.navmesh.query import _astar, _edge_length


def _astar_closed_set(start, goal, edges, point):
    """The textbook A* (a closed set beside the costs), as _astar was written before."""
    gx, gy, gz = point(goal)
    g, parent = {start: 0.0}, {start: -1}
    ux, uy, uz = point(start)
    heap = [(math.sqrt((ux - gx) ** 2 + (uy - gy) ** 2 + (uz - gz) ** 2), 0.0, start)]
    closed = set()
    while heap:
        _, gu, u = heapq.heappop(heap)
        if u == goal:
            out = [u]
            while parent[out[-1]] >= 0:
                out.append(parent[out[-1]])
            return out[::-1]
        if u in closed:
            continue
        closed.add(u)
        for v, w in edges(u):
            if v in closed:
                continue
            ng = gu + w
            if ng < g.get(v, math.inf):
                g[v] = ng
                parent[v] = u
                vx, vy, vz = point(v)
                h = math.sqrt((vx - gx) ** 2 + (vy - gy) ** 2 + (vz - gz) ** 2)
                heapq.heappush(heap, (ng + h, ng, v))
    return None


def _grid_graph(rng, n, drop):
    """An n x n grid on the integers (many equal costs: ties), some nodes raised half a unit,
    with 8-neighbour links and a fraction `drop` of the nodes cut off."""
    pts = [(float(i), 0.0 if rng.random() < 0.7 else 0.5, float(j))
           for i in range(n) for j in range(n)]
    gone = set(np.flatnonzero(rng.random(n * n) < drop).tolist())
    adj = {}
    for i in range(n):
        for j in range(n):
            u = i * n + j
            adj[u] = [] if u in gone else [
                (a * n + b, _edge_length(pts[u], pts[a * n + b]))
                for a in range(i - 1, i + 2) for b in range(j - 1, j + 2)
                if 0 <= a < n and 0 <= b < n and (a, b) != (i, j) and a * n + b not in gone]
    return pts, adj


@pytest.mark.parametrize("seed", range(8))
def test_astar_finds_the_same_node_paths_as_the_closed_set_form(seed):
    rng = np.random.default_rng(seed)
    pts, adj = _grid_graph(rng, 12, 0.2)
    for _ in range(25):
        a, b = (int(x) for x in rng.integers(0, len(pts), 2))
        want = _astar_closed_set(a, b, adj.__getitem__, pts.__getitem__)
        assert _astar(a, b, adj.__getitem__, pts.__getitem__) == want


def test_astar_reports_an_unreachable_goal_and_a_start_at_the_goal():
    pts = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (5.0, 0.0, 0.0)]
    adj = {0: [(1, 1.0)], 1: [(0, 1.0)], 2: []}
    assert _astar(0, 2, adj.__getitem__, pts.__getitem__) is None
    assert _astar(1, 1, adj.__getitem__, pts.__getitem__) == [1]
    assert _astar(0, 1, adj.__getitem__, pts.__getitem__) == [0, 1]


def _csr(pts, adj):
    """(indptr, indices, pos) of a graph given as _grid_graph's adjacency."""
    indptr = np.zeros(len(pts) + 1, dtype=np.int64)
    indptr[1:] = np.cumsum([len(adj[u]) for u in range(len(pts))])
    indices = np.array([v for u in range(len(pts)) for v, _ in adj[u]], dtype=np.int64)
    return indptr, indices, np.array(pts, dtype=np.float64)


@pytest.mark.parametrize("seed", range(8))
def test_the_compiled_coarse_astar_finds_the_python_node_paths(seed):
    """navmesh.astar.coarse_astar (compiled, its own heap) gives _astar's node paths on
    grids full of equal costs (ties broken as Python's tuples compare), unreachable goals and
    a start at the goal included."""
    from baker.navmesh.astar import coarse_astar

    rng = np.random.default_rng(seed)
    pts, adj = _grid_graph(rng, 12, 0.2)
    graph = _csr(pts, adj)
    unreachable = 0
    for _ in range(60):
        a, b = (int(x) for x in rng.integers(0, len(pts), 2))
        want = _astar(a, b, adj.__getitem__, pts.__getitem__)
        assert coarse_astar(*graph, a, b) == want
        unreachable += want is None
    assert unreachable > 0
    assert coarse_astar(*graph, 5, 5) == [5]


def test_find_path_s_coarse_search_is_the_python_one_on_a_level():
    """On a built surface (the two-floor level with its ramp), query._coarse_astar (compiled)
    and the Python search over the coarse graph's lists find the same node paths."""
    from baker.navmesh import query
    from test_navmesh_wander import two_floors

    s = two_floors()
    rng = np.random.default_rng(3)
    n = len(s.coarse_rep)
    for u, v in rng.integers(0, n, (200, 2)).tolist():
        assert query._coarse_astar(s, u, v) == query._coarse_astar_python(s, u, v)
