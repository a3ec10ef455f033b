"""The navigation build's islands and coarse graph, found through the coarse groups (the
components of a graph of about a sixteenth of the samples), against the plain computation on
the samples themselves; and the build's page setting (numpy's huge pages off, then put back)."""

from __future__ import annotations

import importlib

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from baker.navmesh import build as build_module
from baker.navmesh.surface import OPPOSITE
from test_navmesh_scenes import AGENT, env_of, floor

B = importlib.import_module("baker.navmesh.build")


def grid_links(nx: int, nz: int, rng: np.random.Generator, layers: float):
    """A random layered grid of samples with symmetric axis links (some dropped), their cells
    and a random `keep` mask: (links (n, 8), ix, iz, keep)."""
    counts = 1 + (rng.random(nx * nz) < layers).astype(np.int64)
    col = np.repeat(np.arange(nx * nz), counts)
    ix, iz = col // nz, col % nz
    start = np.r_[0, np.cumsum(counts)[:-1]]
    n = len(col)
    links = np.full((n, 8), -1, dtype=np.int32)
    for d, (sx, sz) in enumerate(((1, 0), (0, 1))):
        ok = (ix + sx < nx) & (iz + sz < nz) & (rng.random(n) < 0.85)
        src = np.flatnonzero(ok)
        ncol = (ix[src] + sx) * nz + iz[src] + sz
        layer = rng.integers(0, counts[ncol])           # which sample of the next column
        dst = start[ncol] + layer
        first = np.unique(dst, return_index=True)[1]   # one claim per target sample
        src, dst = src[first], dst[first]
        links[src, d] = dst
        links[dst, OPPOSITE[d]] = src
    keep = rng.random(n) < 0.8
    return links, ix, iz, keep


def reference(links, keep, ix, iz, k, nz, cell, min_area):
    """The islands and coarse labels by connected components of the samples' own graphs."""
    n = len(links)
    ax = links[:, :4]
    has = (ax >= 0) & keep[:, None] & keep[ax]

    def comps(mask):
        rows = np.repeat(np.arange(n), 4)[mask.reshape(-1)]
        g = csr_matrix((np.ones(len(rows)), (rows, ax[mask])), shape=(n, n))
        return connected_components(g, directed=True, connection="strong")

    ncomp, comp = comps(has)
    size = np.bincount(comp[keep], minlength=ncomp)
    big = size * cell * cell >= min_area
    sel = np.flatnonzero(keep & big[comp])
    order = np.argsort(-size[big], kind="stable")
    relabel = np.full(ncomp, -1)
    relabel[np.flatnonzero(big)[order]] = np.arange(int(big.sum()))
    block = (ix // k) * ((nz + k - 1) // k) + iz // k
    same = has & (block[:, None] == block[np.maximum(ax, 0)])
    _, group = comps(same)
    coarse = np.unique(group[sel], return_inverse=True)[1]
    edges = set()
    for d in range(4):
        src = np.intersect1d(np.flatnonzero(has[:, d] & ~same[:, d]), sel)
        edges |= {(int(a), int(b)) for a, b in zip(group[src], group[ax[src, d]])}
    return sel, relabel[comp[sel]], coarse, group, edges


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), nx=st.integers(1, 30), nz=st.integers(1, 30),
       layers=st.floats(0.0, 0.6), k=st.integers(1, 5), min_cells=st.integers(0, 40))
@example(seed=0, nx=1, nz=1, layers=0.0, k=1, min_cells=0)
@example(seed=7, nx=30, nz=30, layers=0.3, k=4, min_cells=12)
def test_islands_through_groups_match_the_sample_graph(seed, nx, nz, layers, k, min_cells):
    rng = np.random.default_rng(seed)
    links, ix, iz, keep = grid_links(nx, nz, rng, layers)
    cell = 0.5
    min_area = min_cells * cell * cell
    sel0, comp0, coarse0, group0, edges0 = reference(links, keep, ix, iz, k, nz, cell, min_area)
    if not len(sel0):
        return                          # nothing kept: the build raises NavError (below)
    groups = B._groups(links, keep, ix, iz, k, nz)
    sel, kept, comp, _ = B._islands(links, keep, groups, cell, min_area, None)
    new_links = B._renumbered(links, kept)
    np.testing.assert_array_equal(sel, sel0)
    np.testing.assert_array_equal(comp, comp0)          # the same numbers, ties in order
    remap = np.full(len(links) + 1, -1)
    remap[sel] = np.arange(len(sel))
    np.testing.assert_array_equal(new_links, remap[links[sel]])
    cells = np.stack([ix[sel], iz[sel]], axis=1)
    lab, rep, indptr, indices = B._coarse(cells, groups.label[sel], groups, k)
    np.testing.assert_array_equal(lab, coarse0)
    assert (lab[rep] == np.arange(lab.max() + 1)).all()  # each node's representative is its own
    # the coarse edges: the border links between the kept samples' groups, both ways
    rows = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
    node_group = np.zeros(lab.max() + 1, dtype=np.int64)
    node_group[lab] = group0[sel]
    got = {(int(node_group[a]), int(node_group[b])) for a, b in zip(rows, indices)}
    assert got == edges0 | {(b, a) for a, b in edges0}


def test_islands_with_nothing_kept_raise():
    links = np.full((3, 8), -1, dtype=np.int32)
    keep = np.zeros(3, dtype=bool)
    groups = B._groups(links, keep, np.arange(3), np.zeros(3, np.int64), 4, 1)
    try:
        B._islands(links, keep, groups, 0.1, 0.0, "here")
    except B.NavError as exc:
        assert "no walkable surface" in str(exc)
    else:
        raise AssertionError("no NavError")


def _huge_pages(value=None):
    toggle = importlib.import_module("numpy._core.multiarray")._set_madvise_hugepage
    before = toggle(True if value is None else value)
    if value is None:
        toggle(before)
    return before


def test_the_build_runs_on_small_pages_and_puts_the_setting_back(monkeypatch):
    seen = []
    real = B._links

    def spy(*args, **kw):
        seen.append(_huge_pages())
        return real(*args, **kw)

    monkeypatch.setattr(B, "_links", spy)
    env = env_of(floor(0.0, 1.0, 0.0, 1.0))
    for setting in (True, False):
        _huge_pages(setting)
        try:
            build_module(env, AGENT)
            assert _huge_pages() is setting
        finally:
            _huge_pages(True)
    assert seen == [False, False]
