"""Root motion (baker/rootmotion.py): the `root` joint, its ground height and heading, and the
three modes, on clips built in code."""

import numpy as np
import pytest

from baker.clip import NodeTrack
from baker.errors import ExportError
from baker.rig.skeleton import forward_kinematics
from baker.rootmotion import apply_root_motion, root_frames, with_root, yaw_quaternions


def _bump_ground(clip):
    """The sine trajectory's ground (y = 0.02 sin(2 pi z / 0.7)) in the clip's placement frame."""
    p = clip.placement
    kb = 2 * np.pi / 0.7
    return lambda pts: 0.02 * np.sin(kb * (pts[:, 2] + p[2])) - p[1]


def test_with_root_puts_root_first_and_keeps_skinning(rig):
    rooted = with_root(rig)
    s0, s1 = rig.skeleton, rooted.skeleton
    assert s1.names == ("root",) + s0.names
    assert s1.parents[0] == -1 and s1.parents[1] == 0
    assert np.array_equal(s1.parents[2:], s0.parents[1:] + 1)
    assert np.array_equal(rooted.spine, np.asarray(rig.spine) + 1)
    used = rig.mesh.weights > 0
    names0 = np.array(s0.names)[rig.mesh.joints[used]]
    names1 = np.array(s1.names)[rooted.mesh.joints[used]]
    assert np.array_equal(names0, names1)
    assert not np.any(rooted.mesh.joints[~used])          # unused slots stay joint 0, weight 0
    # the rest pose is unchanged: the root sits at the skeleton origin with no rotation
    w0, _ = s0.world_rest()
    w1, _ = s1.world_rest()
    assert np.allclose(w1[1:], w0) and np.allclose(w1[0], 0)
    with pytest.raises(ExportError, match="already has a joint"):
        with_root(rooted)


def test_root_mode_leaves_every_joint_where_it_was(clip, rig):
    rooted_clip, rooted, motion = apply_root_motion(clip, rig, "root", _bump_ground(clip))
    assert motion is None
    w0, _ = clip.world(rig.skeleton.parents)
    w1, q1 = rooted_clip.world(rooted.skeleton.parents)
    assert np.abs(w1[:, 1:] - w0).max() < 1e-5
    assert rooted_clip.rotations.shape == (clip.n_frames, clip.n_joints + 1, 4)
    assert np.allclose(np.linalg.norm(rooted_clip.rotations, axis=-1), 1, atol=1e-6)
    # the root turns about +Y only
    assert np.allclose(q1[:, 0, [0, 2]], 0, atol=1e-7)


def test_root_sits_on_the_ground_under_the_body(clip, rig):
    flat, rooted, _ = apply_root_motion(clip, rig, "root", None)
    assert np.all(flat.translations[:, 0, 1] == 0)                # no ground given: y = 0
    bumpy, _, _ = apply_root_motion(clip, rig, "root", _bump_ground(clip))
    w, _ = clip.world(rig.skeleton.parents)
    centre = (w[:, rig.spine] - clip.placement).mean(axis=1)
    ground = _bump_ground(clip)(centre)
    # smoothed over half a second: within the bumps' amplitude of the ground under the centre
    assert np.abs(bumpy.translations[:, 0, 1] - ground).max() < 0.02 + 1e-6
    assert np.allclose(bumpy.translations[:, 0, [0, 2]], centre[:, [0, 2]], atol=1e-6)


@pytest.mark.parametrize("yaw_deg", [0.0, 37.0, -120.0, 180.0])
def test_root_heading_follows_a_straight_body(yaw_deg):
    yaw = np.radians(yaw_deg)
    d = np.array([np.sin(yaw), 0.0, np.cos(yaw)])
    spine = (5.0 - 0.1 * np.arange(21))[None, :, None] * d + np.array([1.0, 0.3, -2.0])
    pos, rot = root_frames(np.repeat(spine, 3, axis=0), fps=30)
    fwd = np.stack([2 * (rot[:, 0] * rot[:, 2] + rot[:, 3] * rot[:, 1]), np.zeros(3),
                    1 - 2 * (rot[:, 0] ** 2 + rot[:, 1] ** 2)], axis=1)   # R @ +Z
    assert np.allclose(fwd, d, atol=1e-9)
    assert np.allclose(pos[:, [0, 2]], spine[0].mean(axis=0)[[0, 2]]) and np.all(pos[:, 1] == 0)


def test_an_upright_body_keeps_the_last_heading():
    fwd = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    q = yaw_quaternions(fwd)
    assert np.allclose(q[1], q[0]) and np.allclose(q[2], q[0])
    assert np.allclose(q[3], [0, 0, 0, 1])


def test_in_place_holds_the_root_and_returns_the_motion(clip, rig):
    root_clip, rooted, _ = apply_root_motion(clip, rig, "root", _bump_ground(clip))
    still, rooted2, motion = apply_root_motion(clip, rig, "in-place", _bump_ground(clip))
    assert rooted2.skeleton.names == rooted.skeleton.names
    assert isinstance(motion, NodeTrack) and motion.node == "root"
    assert np.all(still.translations[:, 0] == 0)
    assert np.all(still.rotations[:, 0] == np.float32([0, 0, 0, 1]))
    assert np.array_equal(still.translations[:, 1:], root_clip.translations[:, 1:])
    assert np.array_equal(motion.translations, root_clip.translations[:, 0])
    # putting the removed motion back gives the world clip
    t = np.array(still.translations, dtype=np.float64)
    q = np.array(still.rotations, dtype=np.float64)
    t[:, 0], q[:, 0] = motion.translations, motion.rotations
    w, _ = forward_kinematics(rooted.skeleton.parents, t, q)
    w0, _ = clip.world(rig.skeleton.parents)
    assert np.abs(w[:, 1:] + clip.placement - w0).max() < 1e-5


def test_world_mode_is_the_identity_and_bad_modes_are_refused(clip, rig):
    assert apply_root_motion(clip, rig, "world") == (clip, rig, None)
    with pytest.raises(ExportError, match="root-motion mode"):
        apply_root_motion(clip, rig, "inplace")


def test_a_fast_turn_of_more_than_half_a_circle_keeps_the_root_turning_its_way():
    """A straight body turning 210 degrees in a second (a crowd creature coiling round,
    crowd of 3 on Recast's undulating level, seed 117942): its heading averaged as vectors over
    the 0.5 s window came near zero and swung 60 degrees in one frame the other way round
    (the head turned 62 degrees a frame against the root). Averaged as angles, the root turns
    smoothly, never faster than the body, and ends on the body's heading."""
    F, fps = 180, 30
    turn = np.radians(np.clip(np.arange(F) - 60, 0, 30) * 7.0)          # 7 deg a frame, 30 frames
    d = np.stack([np.sin(turn), np.zeros(F), np.cos(turn)], axis=1)
    spine = (1.0 - 0.05 * np.arange(21))[None, :, None] * d[:, None, :]
    _, rot = root_frames(spine, fps=fps)
    yaw = np.unwrap(2.0 * np.arctan2(rot[:, 1], rot[:, 3]))
    steps = np.degrees(np.diff(yaw))
    assert steps.min() > -1e-9 and steps.max() <= 7.0 + 1e-9
    assert np.degrees(yaw[[0, -1]]) == pytest.approx([0.0, 210.0], abs=0.01)
