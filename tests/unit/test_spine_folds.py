"""A head that turns back on itself tighter than a segment spacing (a crowd's cornered head:
a tight turn, a hold, a turn on the spot) folds its trail. The chord placement's first crossing
back along the trail then leaps across the fold: each joint that reaches it jumps one or two
spacings in a frame (40 of 100 creatures in a crowd minute, one of whose jumping tails swung a
leg through a neighbour's head). locomotion.body keeps such a joint near where it was: the
crossing nearest its last arc, else swung round the joint ahead at PIVOT_RATE
(trail_kernels._kept)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from baker.config import DEFAULT_RIG, load_rig_config
from baker.geometry.transforms import quat_angle
from baker.locomotion import body
from baker.locomotion.body import body_frames, build_trail
from baker.metrics import spine_jumps
from test_navmesh_scenes import env_of, quad

RIG = load_rig_config(DEFAULT_RIG)
FPS = 30


def hairpin(width: float, speed: float = 0.25, frames: int = 160):
    """The spine walking on the flat up +X, back round a half loop `width` spacings wide and
    down -X again beside its way up, at `speed` spacings a frame."""
    b = RIG.body
    env = env_of(quad((-1, 0, -1), (-1, 0, 1), (1, 0, 1), (1, 0, -1)))
    r = 0.5 * width * b.spacing
    up = np.column_stack([np.linspace(-0.5, 0.0, 400), np.zeros((400, 2))])
    a = np.linspace(0.0, math.pi, 30)[1:-1]
    loop = np.column_stack([r * np.sin(a), np.zeros_like(a), r * (1.0 - np.cos(a))])
    down = np.column_stack([np.linspace(0.0, -0.5, 400), np.zeros(400), np.full(400, 2.0 * r)])
    path = np.vstack([up, loop, down])
    trail = build_trail(path, env.rays, probe=0.1, spacing=b.spacing, clearance=b.clearance)
    head_arc = trail.arc_at(np.linspace(0.35, 0.35 + speed * b.spacing * frames, frames))
    return body_frames(trail, head_arc, b.spacing, b.segments, b.clearance, fps=FPS)


@pytest.mark.parametrize("width", [0.0, 0.3, 0.6])
def test_no_joint_jumps_across_a_hairpin_tighter_than_a_spacing(width, monkeypatch):
    sp = RIG.body.spacing
    bf = hairpin(width)
    pos = bf.positions
    jumps, excess = spine_jumps(pos, sp)
    assert jumps == 0, (jumps, excess)
    # the segments stay rigid and every joint rides at its height over the flat
    gaps = np.linalg.norm(np.diff(pos, axis=1), axis=2) / sp - 1.0
    assert np.abs(gaps).max() < 1e-6
    assert np.abs(pos[..., 1] - RIG.body.clearance).max() < 1e-6
    assert np.degrees(quat_angle(bf.rotations[:-1], bf.rotations[1:])).max() < 30.0
    # the whole body passes the hairpin and lies on the way down again
    assert np.abs(pos[-1, :, 2] - width * sp).max() < 0.05 * sp
    # the first crossing alone leaps across it
    monkeypatch.setattr(body, "PIVOT_RATE", 0.0)
    leaped, excess = spine_jumps(hairpin(width).positions, sp)
    assert leaped > 0 and excess > 1.0, (leaped, excess)


def test_a_body_on_a_smooth_trail_is_placed_as_before(monkeypatch):
    # a loop wider than the fold test: the kept placement never acts (the same bits)
    bf = hairpin(3.0)
    monkeypatch.setattr(body, "PIVOT_RATE", 0.0)
    free = hairpin(3.0)
    assert np.array_equal(bf.positions, free.positions)
    assert np.array_equal(bf.arcs, free.arcs)
