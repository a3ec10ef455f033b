"""A cobra rearing in a valley (locomotion.body.body_frames): the neck's joints are pulled
forward along the trail as it rises, and at the valley's bottom they would turn more than the
30 degree limit in a frame. Such a ramp rises more slowly; the others keep their rate."""

from __future__ import annotations

import numpy as np
import pytest

from baker.config import DEFAULT_RIG, load_rig_config
from baker.geometry.transforms import quat_angle
from baker.locomotion.body import RAISED_RISE, body_frames, build_trail, limit_rise
from baker.locomotion.cobra import lift_profile
from test_navmesh_scenes import env_of, quad

RIG = load_rig_config(DEFAULT_RIG)
W = 0.4   # half the valley's width [m]


def rear_in_valley(slope_deg: float, past: float, speed: float = 0.004, frames: int = 90):
    """A V valley with `slope_deg` sides; the head walks across it at `speed` m per frame and
    starts rearing (the cobra's 0.4 s ramp) as it is `past` metres beyond the bottom."""
    b, c = RIG.body, RIG.cobra
    k = np.tan(np.radians(slope_deg))
    env = env_of(quad((0, W * k, 0), (0, W * k, 0.6), (W, 0, 0.6), (W, 0, 0)),
                 quad((W, 0, 0), (W, 0, 0.6), (2 * W, W * k, 0.6), (2 * W, W * k, 0)))
    xs = np.linspace(0.01, 2 * W - 0.01, 400)
    path = np.column_stack([xs, k * np.abs(xs - W), np.full(400, 0.3)])
    trail = build_trail(path, env.rays, probe=0.1, spacing=b.spacing, clearance=b.clearance)
    head_arc = trail.arc_at(W + past + speed * (np.arange(frames) - 30) - 0.01)
    amount = np.clip((np.arange(frames) - 30) / (c.ramp_time * 30), 0.0, 1.0)
    lift = lift_profile(amount, c.curve, c.height, b.segments)
    bf = body_frames(trail, head_arc, b.spacing, b.segments, b.clearance, lift=lift,
                     rays=env.rays, fps=30, ramp_time=c.ramp_time)
    return bf, lift


@pytest.mark.parametrize("slope, past", [(45, 0.02), (45, 0.05), (35, 0.02)])
def test_rearing_in_a_valley_turns_no_joint_over_the_limit(slope, past):
    bf, lift = rear_in_valley(slope, past)
    turn = np.degrees(quat_angle(bf.rotations[:-1], bf.rotations[1:]))
    assert turn.max() < 30.0, turn.max()           # 37 degrees at 45/0.02 with the fixed ramp
    # the spine keeps its spacing, and the neck still gets (nearly) all the way up
    gaps = np.linalg.norm(np.diff(bf.positions, axis=1), axis=2) / RIG.body.spacing - 1.0
    assert np.abs(gaps).max() < 0.02
    assert bf.lift[-1, 0] >= 0.95 * lift[-1, 0]


def test_a_ramp_on_the_flat_keeps_its_rate():
    bf, lift = rear_in_valley(0.0, 0.05)
    assert np.array_equal(bf.lift, limit_rise(lift, RAISED_RISE * RIG.body.spacing))
