"""Wander targets (random_point_near) are uniform by surface area over the reachable surface,
over all layers (issue 10): an upper floor gets its share of the draws, a slope counts its true
area, and the draw stays inside the 3D sphere.

Scene (the 2 m rig's agent: radius 0.16 m, cell 0.12 m): a 12 x 6 m ground floor (y = 0), a
solid block x 0..4 whose top (y = 2) is an upper floor, and a 30 degree ramp from the block's
edge down to the floor (x 4..7.46, z 1..5). Shares are computed from the samples' areas
(cell^2 / normal_y); draws use fixed seeds, and the tolerance is 4 standard deviations of the
binomial count, so a correct draw passes with any seed.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
import trimesh

from baker.config import DEFAULT_RIG, load_rig_config, scale_rig
from baker.navmesh import build
from test_navmesh_scenes import box, env_of, floor

AGENT = scale_rig(load_rig_config(DEFAULT_RIG), 8.0).navigation
TOP = 2.0
RUN = TOP / math.tan(math.radians(30.0))


@functools.lru_cache(maxsize=None)
def two_floors():
    ramp = trimesh.Trimesh([(4, 0, 1), (4 + RUN, 0, 1), (4, TOP, 1), (4, 0, 5), (4 + RUN, 0, 5),
                            (4, TOP, 5)],
                           [(0, 2, 1), (3, 4, 5), (0, 1, 4), (0, 4, 3), (0, 3, 5), (0, 5, 2),
                            (1, 2, 5), (1, 5, 4)], process=False)
    if ramp.volume < 0:
        ramp.invert()
    return build(env_of(floor(0, 12, 0, 6), box((0, 0, 0), (4, TOP, 6)), ramp), AGENT)


def _shares(s, mask):
    """Surface-area share of each layer (ground, ramp, upper) among samples in mask."""
    area = s.cell_size ** 2 / s.normals[:, 1].astype(np.float64)
    y = s.positions[:, 1]
    layers = [y < 0.05, (y >= 0.05) & (y <= TOP - 0.05), y > TOP - 0.05]
    return np.array([area[mask & m].sum() for m in layers]) / area[mask].sum()


def _fractions(q):
    y = q[:, 1]
    return np.array([np.mean(y < 0.05), np.mean((y >= 0.05) & (y <= TOP - 0.05)),
                     np.mean(y > TOP - 0.05)])


def test_scene_is_one_component_over_three_layers():
    s = two_floors()
    assert s.component_of([10, 0, 3]) == s.component_of([2, TOP, 3]) == 0
    slope = np.degrees(np.arccos(s.normals[:, 1]))
    assert np.count_nonzero(np.abs(slope - 30.0) < 0.5) > 500  # the ramp's samples


@pytest.mark.parametrize("start", [(10.0, 0.0, 3.0), (2.0, TOP, 3.0), (5.5, 0.9, 3.0)])
def test_whole_level_draws_follow_the_area_of_each_floor(start):
    """A radius larger than the level: every reachable point is a candidate, whichever floor
    the creature stands on."""
    s = two_floors()
    rng = np.random.default_rng(7)
    p = s.nearest(start)
    n = 3000
    q = np.array([s.random_point_near(p, 100.0, rng) for _ in range(n)])
    want = _shares(s, s.component == 0)
    assert want[2] > 0.25 and want[1] > 0.15  # the upper floor and the ramp are big parts
    tol = 4.0 * np.sqrt(want * (1 - want) / n)
    assert np.all(np.abs(_fractions(q) - want) <= tol), (_fractions(q), want)


@pytest.mark.parametrize("radius", [1.5, 3.0])
def test_draws_within_a_sphere_follow_its_area(radius):
    """From the middle of the ramp, with a radius of a few metres (the fine grid draw for 1.5 m,
    the coarse-block draw for 3 m): points lie within the 3D sphere, spread by area over the
    ramp and the floors it reaches."""
    s = two_floors()
    rng = np.random.default_rng(11)
    p = s.nearest((4 + RUN / 2, TOP / 2, 3.0))
    n = 3000
    q = np.array([s.random_point_near(p, radius, rng) for _ in range(n)])
    assert np.all(np.linalg.norm(q - p, axis=1) <= radius + 1e-9)
    inside = np.linalg.norm(s.positions - p, axis=1) <= radius
    want = _shares(s, inside & (s.component == 0))
    # sample centres stand in for their cells: allow one cell's rim of the sphere on top
    rim = 2.0 * s.cell_size / radius
    tol = 4.0 * np.sqrt(want * (1 - want) / n) + rim * want
    assert np.all(np.abs(_fractions(q) - want) <= tol), (_fractions(q), want)


def test_a_steep_slope_counts_its_true_area():
    """A 55 degree ramp between two floors: its samples cover 1 / cos 55 = 1.74 times their
    cell's horizontal area, and draws land on it by that true area."""
    rise = 2.0 * math.tan(math.radians(55.0))
    s = build(env_of(floor(0, 4, 0, 4), floor(6, 8, 0, 4, y=rise),
                     trimesh.Trimesh([(4, 0, 0), (4, 0, 4), (6, rise, 4), (6, rise, 0)],
                                     [(0, 1, 2), (0, 2, 3)], process=False)), AGENT)
    on = (s.positions[:, 1] > 0.05) & (s.positions[:, 1] < rise - 0.05)
    assert s.component_of([1, 0, 2]) == s.component_of([7, rise, 2]) == 0
    true_share = (1.0 / s.normals[on, 1]).sum() / (1.0 / s.normals[:, 1]).sum()
    flat_share = on.mean()
    rng = np.random.default_rng(5)
    n = 3000
    q = np.array([s.random_point_near(s.nearest([1, 0, 2]), 100.0, rng) for _ in range(n)])
    frac = np.mean((q[:, 1] > 0.05) & (q[:, 1] < rise - 0.05))
    tol = 4.0 * math.sqrt(true_share * (1 - true_share) / n)
    assert abs(frac - true_share) <= tol
    assert abs(true_share - flat_share) > 3 * tol  # the test tells the two apart


def test_remembered_coarse_draws_are_the_fresh_ones():
    """The coarse draw's candidate nodes and member weights are remembered per surface
    (a crowd's starts draw round one point at a few radii, again and again): draws on a
    surface that remembers them are the draws of one that computes them afresh each time."""
    s = two_floors()
    p = s.nearest((4 + RUN / 2, TOP / 2, 3.0))
    radii = [3.0, 4.5, 100.0, 3.0, 6.0]

    def draws(forget: bool) -> np.ndarray:
        rng = np.random.default_rng(5)
        out = []
        for k in range(200):
            if forget:
                for key in ("coarse_candidates", "coarse_draws_seen", "member_weights"):
                    s._cache.pop(key, None)
            out.append(s.random_point_near(p, radii[k % len(radii)], rng))
        return np.array(out)

    fresh = draws(forget=True)
    for k in ("coarse_candidates", "coarse_draws_seen", "member_weights"):
        s._cache.pop(k, None)
    assert np.array_equal(draws(forget=False), fresh)
    # kept from a draw's second time: each of the radii here comes round again
    assert len(s._cache["coarse_candidates"]) == len(set(radii))
    # a draw round a new point each time (a wander target's) is never kept
    rng = np.random.default_rng(6)
    for q in s.positions[rng.integers(0, len(s.positions), 20)].astype(np.float64):
        s.random_point_near(q, 4.5, rng)
    assert len(s._cache["coarse_candidates"]) == len(set(radii))
