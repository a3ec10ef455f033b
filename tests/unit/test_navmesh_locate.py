"""The navigation's point location (navmesh.query._locate, compiled in navmesh.locate): the
same samples and heights, bit for bit, as the Python reference _locate_few, on a level of
three layers, with points on cell borders, off the grid and not finite."""

from __future__ import annotations

import numpy as np
import pytest

from baker.navmesh.query import _locate, _locate_few
from test_navmesh_wander import TOP, two_floors


def _points(s, rng, n):
    """n points over the level's bounds (and beyond), near each layer's height, a third of
    them moved onto a cell border in x, z or both."""
    x0, z0 = float(s.origin[0]), float(s.origin[1])
    c = s.cell_size
    x = rng.uniform(x0 - 1.0, x0 + c * s.shape[0] + 1.0, n)
    z = rng.uniform(z0 - 1.0, z0 + c * s.shape[1] + 1.0, n)
    y = rng.choice([0.0, 0.5 * TOP, TOP], n) + rng.uniform(-0.3, 0.3, n) * rng.choice([0.05, 1.0], n)
    border = rng.integers(0, 6, n)
    x = np.where(border % 3 == 1, x0 + np.round((x - x0) / c) * c, x)
    z = np.where(border % 3 == 2, z0 + np.round((z - z0) / c) * c, z)
    both = border == 0
    x[both] = x0 + np.round((x[both] - x0) / c) * c
    z[both] = z0 + np.round((z[both] - z0) / c) * c
    return np.column_stack([x, y, z])


@pytest.mark.parametrize("tol", [np.inf, 0.5, 0.02, 0.0])
def test_compiled_location_is_the_python_reference(tol):
    s = two_floors()
    pts = _points(s, np.random.default_rng(7), 3000)
    odd = np.array([[np.nan, 0.0, 1.0], [1.0, np.nan, 1.0], [1.0, 0.0, np.inf],
                    [-np.inf, 0.0, 1.0], [1e30, 0.0, 1.0], [1.0, 0.0, -1e300],
                    [2.0, 1e300, 3.0], [9.2e18, 0.0, 1.0]])
    pts = np.vstack([pts, odd])
    k, h = _locate(s, pts, tol)
    k_ref, h_ref = _locate_few(s, pts, tol)
    assert np.array_equal(k, k_ref)
    assert np.array_equal(h, h_ref, equal_nan=True)
    assert h.dtype == np.float64 and k.dtype == np.int64
    found = k >= 0
    if tol > 0.0:
        # the test means something: points found on every layer, and points found nowhere
        assert found.sum() > 300 and (~found).sum() > 300
        assert {0.0, TOP} <= set(np.round(h[found], 6))


def test_border_points_take_a_neighbouring_column():
    """A point exactly on a cell border whose own column holds no sample at its height is found
    in a neighbouring column (the first of the nudges to find one), as the reference finds it:
    every sample's point moved onto its column's far border in x, and in z."""
    s = two_floors()
    c = s.cell_size
    x0, z0 = float(s.origin[0]), float(s.origin[1])
    p = s.positions.astype(np.float64)
    ix = np.floor((p[:, 0] - x0) / c)
    iz = np.floor((p[:, 2] - z0) / c)
    pts = np.vstack([np.column_stack([x0 + (ix + 1) * c, p[:, 1], p[:, 2]]),
                     np.column_stack([p[:, 0], p[:, 1], z0 + (iz + 1) * c])])
    k, h = _locate(s, pts, 0.05)
    k_ref, h_ref = _locate_few(s, pts, 0.05)
    k_own = _locate_few(s, pts, 0.05, retry=False)[0]
    assert np.array_equal(k, k_ref) and np.array_equal(h, h_ref, equal_nan=True)
    assert np.count_nonzero((k_own < 0) & (k >= 0)) > 20     # found only by a nudge


def test_empty_queries():
    s = two_floors()
    k, h = _locate(s, np.zeros((0, 3)), np.inf)
    assert k.shape == (0,) and h.shape == (0,)
