"""Antennae turn at most SPINE_FRAME_TURN a frame (locomotion.legs._turn_limited_antenna).

The antennae's sweep is timed in seconds, so at a low export rate it adds more to the head's own
turn between frames: at 12 fps a multi-storey bake's antenna turned 35 degrees in a frame, where
the quality limit is 30. Here a head turns 24 degrees a frame while its antenna sweeps 20 degrees
a frame the same way: each bone is held to the limit in the world and relative to the bone it
hangs from, its knee stays at the end of its first bone, and frames that were within the limit
keep their exact values.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from baker.geometry.conventions import UP
from baker.geometry.transforms import quat_angle, quat_conj, quat_mul, quat_rotate
from baker.locomotion.body import SPINE_FRAME_TURN
from baker.locomotion.legs import _turn_limited_antenna

LIM = math.radians(SPINE_FRAME_TURN)


def head_and_antenna(head_step: float, sweep_step: float, frames: int = 40):
    """Head rotations turning head_step degrees a frame about UP for the first half, then still;
    an antenna whose first bone sweeps sweep_step degrees a frame relative to the head, its second
    bone bent 30 degrees from the first: (q, origins, r1, r2, knee, l1)."""
    f = np.arange(frames)
    yaw = np.radians(head_step) * np.minimum(f, frames // 2)
    q = Rotation.from_euler("y", yaw[:, None]).as_quat()
    sweep = np.radians(sweep_step) * np.minimum(f, frames // 2)
    local1 = Rotation.from_euler("yx", np.stack([sweep, np.full(frames, 1.2)], -1)).as_quat()
    r1 = quat_mul(q, local1)
    r2 = quat_mul(r1, Rotation.from_euler("x", np.full((frames, 1), 0.5)).as_quat())
    o = np.tile([0.0, 0.01, 0.02], (frames, 1))
    l1 = 0.006
    knee = o + quat_rotate(r1, np.broadcast_to(UP, o.shape)) * l1
    return q, o, r1, r2, knee, l1


def test_a_fast_antenna_is_held_to_the_limit_in_the_world_and_against_its_parent():
    q, o, r1, r2, knee, l1 = head_and_antenna(24.0, 20.0)
    assert quat_angle(r1[:-1], r1[1:]).max() > math.radians(34.0)      # the case: 36 a frame
    a1, a2, k = _turn_limited_antenna(q, o, r1, r2, knee, l1)
    for rot, parent in ((a1, q), (a2, a1)):
        assert quat_angle(rot[:-1], rot[1:]).max() <= LIM + 1e-9
        local = quat_mul(quat_conj(parent), rot)
        assert quat_angle(local[:-1], local[1:]).max() <= LIM + 1e-9
    np.testing.assert_allclose(k, o + quat_rotate(a1, np.broadcast_to(UP, o.shape)) * l1,
                               atol=1e-12)
    # it catches up with the sweep once the head stops
    assert quat_angle(a1[-1:], r1[-1:])[0] < 1e-9


def test_an_antenna_within_the_limit_keeps_its_exact_values():
    q, o, r1, r2, knee, l1 = head_and_antenna(10.0, 8.0)
    a1, a2, k = _turn_limited_antenna(q, o, r1, r2, knee, l1)
    assert np.array_equal(a1, r1) and np.array_equal(a2, r2) and np.array_equal(k, knee)
