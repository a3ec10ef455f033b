"""A head that turns round in a loop about as wide as a segment spacing (a head cornered in a
crowd turning on the spot) leaves a knot in its trail. Each joint that passes the knot swings
round at the body's turn limit; two neighbours can swing in opposite senses and turn twice the
limit against each other (48 degrees in crowds, against the 30 degree quality limit).
locomotion.body limits every spine joint's turn in a frame relative to the joint ahead as well
as in the world (transforms.limit_rotation with the joint ahead as its parent)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from baker.config import DEFAULT_RIG, load_rig_config
from baker.geometry.transforms import (limit_rotation, normalize, quat_about, quat_angle,
                                       quat_conj, quat_mul, quat_rotate)
from baker.locomotion import body
from baker.locomotion.body import SPINE_FRAME_TURN, body_frames, build_trail
from test_navmesh_scenes import env_of, quad

RIG = load_rig_config(DEFAULT_RIG)
LIMIT = math.radians(SPINE_FRAME_TURN)
Y = np.array([0.0, 1.0, 0.0])


def steps(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Degrees turned a frame by spine rotations q (F, S, 4): in the world (F-1, S) and
    relative to the joint ahead (F-1, S-1)."""
    local = quat_mul(quat_conj(q[:, :-1]), q[:, 1:])
    return (np.degrees(quat_angle(q[:-1], q[1:])),
            np.degrees(quat_angle(local[:-1], local[1:])))


def test_a_child_swinging_against_its_parent_keeps_both_limits():
    # the parent turns +20 degrees a frame about +Y, the child wants -20: 40 against it
    f = np.arange(30)
    turn = np.where(f < 10, 0.0, np.radians(20.0) * np.minimum(f - 10, 9))
    parent = quat_about(np.tile(Y, (30, 1)), turn)
    want = quat_about(np.tile(Y, (30, 1)), -turn)
    out = limit_rotation(want, LIMIT, parent=parent)
    world = quat_angle(out[:-1], out[1:])
    local = quat_mul(quat_conj(parent), out)
    assert world.max() <= LIMIT + 1e-9
    assert quat_angle(local[:-1], local[1:]).max() <= LIMIT + 1e-9
    assert np.array_equal(out[:11], want[:11])      # followed exactly until it turns too fast
    # and a wanted rotation within both limits is returned as it is
    assert limit_rotation(parent, LIMIT, parent=parent) is parent


def knot(radius: float, degrees: float, speed: float, frames: int = 125):
    """The spine walking on the flat through a loop of `radius` that turns the head `degrees`
    round, at `speed` metres a frame."""
    b = RIG.body
    env = env_of(quad((-1, 0, -1), (-1, 0, 1), (1, 0, 1), (1, 0, -1)))
    lead = np.column_stack([np.linspace(-0.6, 0.0, 200), np.zeros((200, 2))])
    a = np.linspace(0.0, np.radians(degrees), 40)
    loop = np.column_stack([radius * np.sin(a), np.zeros_like(a), radius * (1 - np.cos(a))])
    away = loop[-1] + np.linspace(0.0, 0.6, 200)[:, None] * np.array(
        [np.cos(a[-1]), 0.0, np.sin(a[-1])])
    path = np.vstack([lead, loop[1:-1], away])
    trail = build_trail(path, env.rays, probe=0.1, spacing=b.spacing, clearance=b.clearance)
    head_arc = trail.arc_at(np.linspace(0.65, 0.65 + speed * frames, frames))
    return body_frames(trail, head_arc, b.spacing, b.segments, b.clearance, fps=30)


@pytest.mark.parametrize("degrees", [230.0, 300.0, 360.0])
def test_no_spine_joint_turns_over_the_limit_against_the_joint_ahead_through_a_knot(
        degrees, monkeypatch):
    bf = knot(0.01, degrees, 0.008)
    world, local = steps(bf.rotations)
    assert world.max() <= SPINE_FRAME_TURN + 1e-6, world.max()
    assert local.max() <= SPINE_FRAME_TURN + 1e-6, local.max()
    # each joint limited in the world alone turns up to twice the limit against its neighbour
    monkeypatch.setattr(body, "_turn_limited", lambda frames: frames)
    free = knot(0.01, degrees, 0.008).rotations
    assert np.array_equal(free[-1], bf.rotations[-1])
    _, alone = steps(np.stack([limit_rotation(free[:, j], LIMIT)
                               for j in range(free.shape[1])], axis=1))
    assert alone.max() > 30.0, alone.max()
    # once the whole body is past the knot every joint faces the joint ahead again
    forward = quat_rotate(bf.rotations[-20:, 1:], np.array([0.0, 0.0, 1.0]))
    chord = normalize(bf.positions[-20:, :-1] - bf.positions[-20:, 1:])
    off = np.degrees(np.arccos(np.clip(np.einsum("fsi,fsi->fs", forward, chord), -1, 1)))
    assert off.max() < 1.0, off.max()
