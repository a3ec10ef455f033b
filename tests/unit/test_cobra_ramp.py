"""A cobra rearing in a valley (locomotion.body.body_frames): the neck's joints are pulled
forward along the trail as it rises, and at the valley's bottom they would turn more than the
30 degree limit in a frame. Such a ramp rises more slowly; the others keep their rate."""

from __future__ import annotations

import numpy as np
import pytest

from baker.config import DEFAULT_RIG, load_rig_config
from baker.geometry.transforms import normalize, quat_angle, quat_rotate
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


def rear_twice_on_a_circle():
    """The head walks a circle of radius 0.3 m on the flat (a turning-radius loop, as a head
    blocked by other bodies walks) and rears twice, each time in a single frame: both ramps
    turn the neck too fast and are slowed, and between them the body has turned a quarter of
    the way round."""
    b = RIG.body
    env = env_of(quad((-1, 0, -1), (-1, 0, 1), (1, 0, 1), (1, 0, -1)))
    a = np.linspace(0.0, 2.0 * np.pi, 800)
    path = np.column_stack([0.3 * np.sin(a), np.zeros_like(a), 0.3 - 0.3 * np.cos(a)])
    lead = np.column_stack([np.linspace(-0.6, 0.0, 60, endpoint=False), np.zeros((60, 2))])
    path = np.vstack([lead, path])
    trail = build_trail(path, env.rays, probe=0.1, spacing=b.spacing, clearance=b.clearance)
    frames = 150
    head_arc = trail.arc_at(np.linspace(0.7, 0.7 + 0.006 * frames, frames))
    amount = np.zeros(frames)
    amount[30:55] = 1.0
    amount[95:120] = 1.0
    lift = lift_profile(amount, RIG.cobra.curve, RIG.cobra.height, b.segments)
    return body_frames(trail, head_arc, b.spacing, b.segments, b.clearance, lift=lift,
                       rays=env.rays, fps=30, ramp_time=RIG.cobra.ramp_time), lift


def test_slowed_ramps_keep_every_joint_facing_the_joint_ahead():
    # the slowed ramps' frames are placed again on their own; the joints' directions are
    # taken over all frames (taken over those frames alone, a joint's turn limit saw the
    # quarter turn between the two ramps as one frame's and swung it 90 degrees off its
    # chord: 52 degree joint turns in a 10-creature crowd)
    bf, lift = rear_twice_on_a_circle()
    assert not np.array_equal(bf.lift, lift)        # both ramps were slowed
    forward = quat_rotate(bf.rotations[:, 1:], np.array([0.0, 0.0, 1.0]))
    chord = normalize(bf.positions[:, :-1] - bf.positions[:, 1:])
    off = np.degrees(np.arccos(np.clip(np.einsum("fsi,fsi->fs", forward, chord), -1, 1)))
    assert off.max() < 1.0, off.max()
    turn = np.degrees(quat_angle(bf.rotations[:-1], bf.rotations[1:]))
    assert turn.max() < 30.0, turn.max()



def test_the_kept_joint_curve_gives_the_profile_computed_afresh():
    """lift_profile keeps the curve's values at the joints per (curve, segments): its lifts
    are height * ease * curve_values at 1 - i/n bit for bit, for any amount and curve, and
    the kept values cannot be written to."""
    from baker.locomotion import cobra

    rng = np.random.default_rng(2)
    curves = [((0.0, 0.0), (0.6667, 0.0), (0.85, 0.35), (1.0, 1.0)), ((0.0, 0.2), (1.0, 0.9)),
              [[0.0, 0.0], [0.5, 0.7], [1.0, 1.0]]]
    for curve in curves:
        for segments in (5, 21):
            a = np.r_[0.0, 1.0, rng.uniform(-0.2, 1.2, 30)]
            got = cobra.lift_profile(a, curve, 0.04, segments)
            c = np.clip(a, 0.0, 1.0)
            want = (0.04 * (c * c * (3.0 - 2.0 * c))[:, None]
                    * cobra.curve_values(curve, 1.0 - np.arange(segments) / (segments - 1))[None, :])
            assert got.tobytes() == want.tobytes()
    kept = cobra._joint_curve(cobra._hashable(curves[0]), 21)
    with pytest.raises(ValueError):
        kept[0] = 1.0
