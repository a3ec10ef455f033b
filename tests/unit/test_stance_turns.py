"""A planted leg is lifted before a frame that would turn one of its bones more than the swing
limit, in the world or, for the upper bone, in its segment's own space (legs._stance_turns): a
segment turning one way while the planted leg turns the other adds the two. A showcase bake
(seed 101037) turned `leg_L_16_upper` 30.8 deg in its segment's space in the frame after its
foot landed, with 23 deg in the world and the segment's own 9 deg."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from baker.config import DEFAULT_RIG, load_rig_config
from baker.locomotion.legs import SWING_TURN, _stance_turns
from baker.rig.limbs import leg_layout

RIG = load_rig_config(DEFAULT_RIG)


def turns(segment_yaw_deg: np.ndarray) -> np.ndarray:
    """(W-1,) degrees for leg L_01 with its hip, foot and knee pole fixed in the world while
    its segment's frame yaws through `segment_yaw_deg` (W,)."""
    lay = leg_layout(RIG)
    W = len(segment_yaw_deg)
    hip = np.tile(lay.hip[0], (1, W, 1))
    hold = lay.anchor[:1]                         # its neutral foothold
    fwd = np.tile([0.0, 0.0, 1.0], (1, W, 1))
    left = np.tile([1.0, 0.0, 0.0], (1, W, 1))
    q_inv = Rotation.from_euler("y", -np.radians(segment_yaw_deg)[:, None]).as_quat()[None]
    return _stance_turns(hip, hold, fwd, left, q_inv, lay, np.array([0]), RIG.legs.knee_out)[0]


def test_a_still_leg_under_a_still_segment_does_not_turn():
    assert turns(np.zeros(4)).max() < 1e-6


def test_a_segment_turning_under_a_leg_still_in_the_world_turns_it_in_the_segments_space():
    t = turns(np.array([0.0, 14.0, 42.0, 50.0]))
    np.testing.assert_allclose(t, [14.0, 28.0, 8.0], atol=1e-6)
    assert t[1] > SWING_TURN          # the frame first_bad lifts the foot before
