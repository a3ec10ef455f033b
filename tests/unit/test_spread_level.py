"""Spreading crowded neighbours keeps a foothold on level ground (legs._spread_neighbours).

A foot that the spreading pushed to a leaf's edge, a centimetre under the leaf, could only be
reached by a tip bone threading under it (default scene, seed 111002: a tip bone through the
leaf in the last frames of that swing)."""

from __future__ import annotations

import numpy as np
import trimesh

from baker.environment.rays import RayCaster
from baker.locomotion.legs import (EDGE_CLEAR, NEIGHBOUR_GAP, PLAN_REACH, _spread_neighbours,
                                   is_level)

SPACING = 0.0125             # the default rig's segment spacing [m]
GAP = NEIGHBOUR_GAP * SPACING
EDGE = EDGE_CLEAR * PLAN_REACH * (0.0275 + 0.03)


def _leaf(x0, x1, z0, z1):
    """A one-sided leaf 12 mm over the floor over x0..x1, z0..z1 (vertices, faces)."""
    v = np.array([[x0, 0.012, z0], [x1, 0.012, z0], [x1, 0.012, z1], [x0, 0.012, z1]])
    return v, np.array([[0, 2, 1], [0, 3, 2]])


def _floor_and_leaves(window: bool = False) -> RayCaster:
    """A floor at y = 0 and a leaf 12 mm over it covering x < 0; with `window`, three more
    round a 22.5 mm x 18 mm window of floor: every spot the crowded feet below could step to
    is beside a leaf's edge."""
    leaves = [_leaf(-0.2, 0.0, -0.2, 0.2)]
    if window:
        leaves += [_leaf(0.0225, 0.2, -0.2, 0.2), _leaf(0.0, 0.0225, 0.009, 0.2),
                   _leaf(0.0, 0.0225, -0.2, -0.009)]
    v = [np.array([[-0.2, 0, -0.2], [0.2, 0, -0.2], [0.2, 0, 0.2], [-0.2, 0, 0.2]])]
    f = [np.array([[0, 2, 1], [0, 3, 2]])]
    for lv, lf in leaves:
        f.append(lf + sum(len(x) for x in v))
        v.append(lv)
    return RayCaster(trimesh.Trimesh(np.concatenate(v), np.concatenate(f), process=False))


def _spread(level: bool, window: bool = False):
    """Legs L_01 (front, landed first) and L_02 (landed later), planted 2.5 mm apart, 1 cm
    from the leaf's edge; the body lies toward +x."""
    rays = _floor_and_leaves(window)
    F, L = 6, 4
    holds = np.zeros((1, L, 3))
    holds[0, 0] = [0.0125, 0.0, 0.0]
    holds[0, 2] = [0.0100, 0.0, 0.0]
    holds[0, 1] = holds[0, 3] = [0.1, 0.0, 0.1]
    Ts = np.array([[0, 0, 1, 0]])
    cidx = np.zeros((F, L), np.int64)
    contact = np.zeros((F, L), bool)
    contact[:, [0, 2]] = True
    up = np.broadcast_to([0.0, 1.0, 0.0], (F, L, 3))
    inward = np.broadcast_to([1.0, 0.0, 0.0], (F, L, 3))
    out = _spread_neighbours(holds, Ts, cidx, contact, GAP, rays, up, probe=0.0225,
                             level=(EDGE, inward) if level else None)
    return rays, out[0, [0, 2]]


def test_the_later_foot_is_not_pushed_off_level_ground_beside_a_leaf_edge():
    rays, (front, rear) = _spread(level=True)
    assert np.linalg.norm(front - rear) >= GAP
    level = is_level(rays, np.stack([front, rear]), np.array([[0.0, 1, 0]] * 2),
                     np.array([[1.0, 0, 0]] * 2), EDGE)
    assert level.all()
    assert rear[0] == 0.0100            # the front foot stepped away instead


def test_without_the_level_rule_the_push_takes_the_foot_beside_the_leaf():
    rays, (front, rear) = _spread(level=False)
    assert np.linalg.norm(front - rear) >= GAP
    assert rear[0] < 0.0100
    assert not is_level(rays, rear[None], np.array([[0.0, 1, 0]]), np.array([[1.0, 0, 0]]),
                        EDGE).any()


def test_when_no_step_keeps_a_hold_level_the_feet_still_step_apart():
    """Default 110347: with level holds kept level whatever it cost, two planted feet stayed
    0.188 spacing apart. Feet apart come first: when every move that keeps the hold level is
    blocked, the later foot steps off level ground."""
    rays, (front, rear) = _spread(level=True, window=True)
    up, inward = np.array([[0.0, 1, 0]] * 2), np.array([[1.0, 0, 0]] * 2)
    start = np.array([[0.0125, 0.0, 0.0], [0.0100, 0.0, 0.0]])
    assert is_level(rays, start, up, inward, EDGE).all()
    assert np.linalg.norm(front - rear) >= GAP
    assert not is_level(rays, np.stack([front, rear]), up, inward, EDGE).all()
