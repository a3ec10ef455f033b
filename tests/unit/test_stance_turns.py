"""A planted leg is lifted before a frame that would turn one of its bones more than the swing
limit, in the world or, for the upper bone, in its segment's own space (legs._stance_turns): a
segment turning one way while the planted leg turns the other adds the two. A showcase bake
(seed 101037) turned `leg_L_16_upper` 30.8 deg in its segment's space in the frame after its
foot landed, with 23 deg in the world and the segment's own 9 deg. The knee's fold counts too
(the tip bone in the upper bone's space, as the bake is judged): a hip that comes a little
nearer its planted foot bends the knee by about twice what it turns either bone (a crowd
creature of seed 117600, its trunk brought a spacing forward along a coiled trail in one
frame: leg_L_12_tip 30.5 deg, 22.8 in the world; 27.4 deg now)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from baker.config import DEFAULT_RIG, load_rig_config
from baker.geometry.ik import two_bone_ik
from baker.geometry.transforms import normalize
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


def _window(reach_fracs, leg: int = 20):
    """A planted foot at the origin and leg `leg`'s hip straight above-out of it at the given
    fractions of the leg's full length, the body still (fwd +Z, left +X, no segment turn)."""
    lay = leg_layout(RIG)
    full = lay.l1 + lay.l2
    line = normalize(np.array([lay.side[leg] * 1.0, 1.0, 0.0]))   # foot -> hip, out and up
    W = len(reach_fracs)
    hip = (np.asarray(reach_fracs)[:, None] * full * line)[None]    # (1, W, 3)
    fwd = np.broadcast_to([0.0, 0.0, 1.0], (1, W, 3))
    left = np.broadcast_to([1.0, 0.0, 0.0], (1, W, 3))
    q_inv = np.broadcast_to([0.0, 0.0, 0.0, 1.0], (1, W, 4))
    return lay, hip, fwd, left, q_inv, np.zeros((1, 3)), np.array([leg])


def _judged_steps(lay, hip, fwd, left, leg):
    """(W-1,) the largest per-frame turn, in degrees, of the two IK bones in the world and of
    the tip bone relative to the upper bone, measured as metrics measures a bake."""
    target = np.zeros_like(hip[0])
    side = lay.side[[leg]]
    pole = (side * np.cross(fwd[0], normalize(target - hip[0]))[None])[0]   # leg_pole, knee_out 0
    sol = two_bone_ik(hip[0], target, pole, lay.l1, lay.l2)
    upper = normalize(sol.mid - hip[0])
    tip = normalize(sol.end - sol.mid)

    def ang(a, b):
        return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))

    world = np.maximum(ang(upper[1:], upper[:-1]), ang(tip[1:], tip[:-1]))
    knee = ang(upper, tip)                                  # the knee's bend
    return np.maximum(world, np.abs(np.diff(knee))), np.abs(np.diff(knee))


def test_a_fast_knee_fold_counts_as_a_fast_turn():
    # near a straight knee, the hip closing in by 12 % of the leg folds the knee ~2x as fast
    # as it turns either bone in the world
    lay, hip, fwd, left, q_inv, hold, legs = _window([0.93, 0.93, 0.81, 0.81])
    got = _stance_turns(hip, hold, fwd, left, q_inv, lay, legs, 0.0)[0]
    judged, fold = _judged_steps(lay, hip, fwd, left, legs[0])
    assert fold[1] > SWING_TURN                 # the bake's metric sees a fast fold ...
    assert got[1] >= fold[1] - 1e-6             # ... and so does the check that lifts the foot
    assert got[1] > SWING_TURN
    assert np.all(got[[0, 2]] < 1e-3)           # still frames: no turn


def test_stance_turns_bound_the_judged_turns():
    rng = np.random.default_rng(117800)
    for _ in range(30):
        fr = np.clip(0.6 + np.cumsum(rng.normal(0.0, 0.06, 6)), 0.3, 0.97)
        lay, hip, fwd, left, q_inv, hold, legs = _window(fr, leg=int(rng.integers(0, 40)))
        got = _stance_turns(hip, hold, fwd, left, q_inv, lay, legs, 0.0)[0]
        judged, _ = _judged_steps(lay, hip, fwd, left, legs[0])
        np.testing.assert_array_less(judged - 1e-6, got)
