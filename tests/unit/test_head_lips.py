"""The head steps over a riser's lip between frames (locomotion.body.step_over_lips).

A low obstacle whose sides lean a little off vertical shows a strip a few millimetres wide from
above. A head sampled over that strip has a near-vertical face straight below it, which the
files read as a head on a 79 degree slope, so no frame may draw it there."""

from __future__ import annotations

import math

import numpy as np
import trimesh

from baker.config import DEFAULT_RIG, load_rig_config
from baker.locomotion.body import build_trail, step_over_lips
from test_navmesh_scenes import env_of, floor

RIG = load_rig_config(DEFAULT_RIG)
LEAN = math.radians(11.0)   # the riser's sides, off vertical
LIMIT = 60.0                # the quality limit on the head's slope [deg]


def lean_riser(h: float, x0: float = 0.4, x1: float = 0.6):
    """A floor and a 0.6 m wide block across it, `h` high, whose sides lean LEAN inwards."""
    inset = h * math.tan(LEAN)
    pts = [(x, y, z) for (x, y) in ((x0, 0.0), (x1, 0.0), (x0 + inset, h), (x1 - inset, h))
           for z in (0.0, 0.6)]
    return env_of(floor(0.0, 1.0, 0.0, 0.6), trimesh.convex.convex_hull(np.array(pts)))


def head_slopes(trail, arc, rays) -> np.ndarray:
    """Degrees: the face a ray straight down from the head meets, as inspect.judge reads it."""
    body = RIG.body
    pts = np.array([np.interp(arc, trail.cum, trail.points[:, k]) for k in range(3)]).T
    h = rays.cast_down(pts, body.clearance, max_distance=0.5 * body.length)
    return np.degrees(np.arccos(np.clip(np.abs(np.nan_to_num(h.normals[:, 1], nan=1.0)), 0, 1)))


def test_no_frame_draws_the_head_over_a_leaning_riser():
    body = RIG.body
    h = 0.08 * body.length                     # a 2 cm step, climbable (up to 0.1 BL)
    env = lean_riser(h)
    path = np.column_stack([np.linspace(0.1, 0.9, 200), np.zeros(200), np.full(200, 0.3)])
    trail = build_trail(path, env.rays, probe=0.025, spacing=body.spacing,
                        clearance=body.clearance)
    # the head crossing at a slow 1 mm per frame: several frames fall on each lip's strip
    arc = np.arange(trail.cum[0], trail.cum[-1], 1e-3)
    before = head_slopes(trail, arc, env.rays)
    assert (before > LIMIT).sum() >= 4, "the scene must put frames over the strips"
    reach = 0.5 * body.spacing
    out = step_over_lips(trail, arc, env.rays, body.clearance, math.radians(58.0), reach=reach,
                         depth=0.5 * body.length)
    after = head_slopes(trail, out, env.rays)
    assert after.max() <= LIMIT, after.max()
    # the frames over a strip move, each by less than its reach, the others stay but for a
    # frame a moved one passed; the head never goes backwards along its trail
    moved = out != arc
    assert np.all(moved[before > 58.0])
    assert moved.sum() <= (before > 58.0).sum() + 4
    assert np.abs(out - arc).max() <= reach + 1e-9
    assert np.all(np.diff(out) >= 0.0)


def test_a_long_steep_face_is_left_alone():
    """Where no walkable face lies within reach (a head on a steep slope) the arcs stay."""
    body = RIG.body
    env = env_of(floor(0.0, 1.0, 0.0, 0.6),
                 trimesh.convex.convex_hull(np.array(
                     [(x, y, z) for (x, y) in ((0.4, 0.0), (0.6, 0.0), (0.6, 0.3))
                      for z in (0.0, 0.6)])))   # a 56 degree wedge, then a 90 degree wall
    path = np.column_stack([np.linspace(0.1, 0.9, 200), np.zeros(200), np.full(200, 0.3)])
    trail = build_trail(path, env.rays, probe=0.4, spacing=body.spacing,
                        clearance=body.clearance)
    arc = np.arange(trail.cum[0], trail.cum[-1], 1e-3)
    out = step_over_lips(trail, arc, env.rays, body.clearance, math.radians(50.0),
                         reach=0.5 * body.spacing, depth=0.5 * body.length)
    mid = (np.interp(arc, trail.cum, trail.points[:, 0]) > 0.45) & (
        np.interp(arc, trail.cum, trail.points[:, 0]) < 0.55)
    assert mid.any()
    assert np.array_equal(out[mid], arc[mid])
