"""The walking legs are planned over margins around the bake's frames (legs.py
_planned_with_margins): every foot has landed by frame 0, and a swing under way at the last
frame keeps its pace instead of being squeezed into the frames left."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from baker.config import DEFAULT_RIG, load_rig_config
from baker.environment.rays import RayCaster
from baker.geometry.transforms import quat_angle, quat_conj, quat_mul
from baker.locomotion.body import BodyFrames
from baker.locomotion.legs import leg_frames
from baker.rig.limbs import leg_layout

RIG = load_rig_config(DEFAULT_RIG)


def walking_body(speed: float, seconds: float, fps: int = 30):
    """A straight spine walking along +Z on a flat floor at `speed` m/s from the first frame to
    the last (no start, no stop)."""
    b = RIG.body
    t = np.arange(int(round(seconds * fps)) + 1) / fps
    arc = b.length + speed * t
    s = arc[:, None] - b.spacing * np.arange(b.segments)[None, :]
    pos = np.stack([np.zeros_like(s), np.full_like(s, b.clearance), s], axis=-1)
    rot = np.zeros(s.shape + (4,))
    rot[..., 3] = 1.0
    normals = np.broadcast_to(np.array([0.0, 1.0, 0.0]), pos.shape).copy()
    return BodyFrames(positions=pos, rotations=rot, normals=normals,
                      ground=np.zeros(s.shape)), arc, t


@pytest.fixture(scope="module", params=[3.0, 3.1, 3.2, 3.3], ids=lambda s: f"{s:g}s")
def walk(request):
    """Clips of a few lengths, so the last frame falls at different points of the gait."""
    floor = trimesh.Trimesh([[-2, 0, -2], [2, 0, -2], [2, 0, 4], [-2, 0, 4]],
                            [[0, 2, 1], [0, 3, 2]], process=False)
    bf, arc, t = walking_body(speed=RIG.locomotion.max_speed * RIG.body.length,
                              seconds=request.param)
    return bf, leg_frames(bf, arc, t, RayCaster(floor), RIG)


def test_every_foot_is_planted_at_the_first_frame(walk):
    _, lf = walk
    assert lf.contacts[0].all()
    assert np.allclose(lf.feet[0, :, 1], 0.0, atol=1e-6)         # on the floor, not in it


def test_the_last_frames_turn_no_leg_joint_faster_than_the_rest(walk):
    """However the clip ends, the legs' last frames turn no joint more than the bake's limit
    (30 deg) and no more than the middle of the clip does."""
    bf, lf = walk
    lay = leg_layout(RIG)
    q = lf.rotations
    q_seg = bf.rotations[:, lay.segment]
    q_u, q_t = q[:, 0:2 * lay.n_legs:2], q[:, 1:2 * lay.n_legs:2]
    steps = np.maximum.reduce([np.degrees(quat_angle(x[1:], x[:-1])) for x in
                               (q_u, q_t, quat_mul(quat_conj(q_seg), q_u),
                                quat_mul(quat_conj(q_u), q_t))]).max(axis=1)
    assert steps[-10:].max() < 30.0
    assert steps[-10:].max() <= steps[30:-30].max() + 1.0
