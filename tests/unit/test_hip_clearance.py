"""The trail raised under placed hips (locomotion.body.raised_for_hips, solve.solve).

build_trail keeps the hips clear of the ground on either side of the head's path. A joint's
hips lie across its own facing (the chord to the joint ahead), which in a tight turn can be far
off the path's: they then pass over ground the path's sides never sampled. Here a low platform
stands beside a straight path, between the path and where its side samples fall, and the body's
joints face 40 degrees off the path: their hips are inside the platform until the trail is
raised at the joints' arcs. A multi-storey crowd found it (creature 6 of 8, seed 114500: hips
2 mm inside the corner of a 0.18 m platform beside the walked floor).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from baker.config import DEFAULT_RIG, load_rig_config
from baker.geometry.transforms import quat_rotate
from baker.locomotion.body import HIP_CLEAR, BodyFrames, build_trail, place_chain, raised_for_hips
from baker.locomotion.legs import hip_extent, hip_layout
from test_navmesh_scenes import box, env_of, floor

RIG = load_rig_config(DEFAULT_RIG)
BODY = RIG.body
HIPS, JOINTS = hip_layout(RIG)
OFFSET, DROP = hip_extent(RIG)
TOP = 0.85 * BODY.clearance   # the platform's height: under the joints, over their hips


def scene(platform: bool):
    """A floor, and (platform=True) a box beside the path along +x at z = 0 that the path's
    side samples (at z = +-OFFSET) miss: z from 0.45 to 0.9 OFFSET, x from 0.3 to 0.34 m."""
    parts = [floor(-0.2, 1.0, -0.3, 0.3)]
    if platform:
        parts.append(box((0.30, 0.0, 0.45 * OFFSET), (0.34, TOP, 0.9 * OFFSET)))
    return env_of(*parts)


def frames(trail, yaw_deg: float) -> BodyFrames:
    """The spine placed at arcs that carry it past the platform, every joint turned `yaw_deg`
    from the path about UP."""
    arcs = np.linspace(0.3, 0.6, 31)
    pos, s = place_chain(trail, arcs, np.full((len(arcs), BODY.segments), BODY.clearance),
                         BODY.spacing)
    q = Rotation.from_euler("y", math.radians(90.0 + yaw_deg)).as_quat()   # +Z forward -> +X
    rot = np.broadcast_to(q, pos.shape[:-1] + (4,)).copy()
    return BodyFrames(positions=pos, rotations=rot, normals=np.zeros_like(pos),
                      ground=np.zeros(pos.shape[:-1]), arcs=s)


def hip_clearance(env, bf: BodyFrames) -> np.ndarray:
    """(F, L) each hip's height above the platform top where it is over the platform (inf
    elsewhere)."""
    q = bf.rotations[:, JOINTS]
    hip = bf.positions[:, JOINTS] + quat_rotate(q, np.broadcast_to(HIPS, q.shape[:-1] + (3,)))
    over = ((hip[..., 0] > 0.30) & (hip[..., 0] < 0.34) & (hip[..., 2] > 0.45 * OFFSET)
            & (hip[..., 2] < 0.9 * OFFSET))
    return np.where(over, hip[..., 1] - TOP, np.inf)


def trail_of(env):
    path = np.column_stack([np.linspace(-0.1, 0.9, 400), np.zeros(400), np.zeros(400)])
    return build_trail(path, env.rays, probe=0.5 * RIG.navigation.height, spacing=BODY.spacing,
                       clearance=BODY.clearance, hips=(OFFSET, DROP))


def test_the_paths_sides_miss_the_platform_and_turned_hips_sink_into_it():
    """The scene does what it is for: the trail along the path ignores the platform, and
    joints turned 40 degrees off the path put hips inside it."""
    with_box, without = trail_of(scene(True)), trail_of(scene(False))
    np.testing.assert_allclose(with_box.points, without.points, atol=1e-6)
    assert (hip_clearance(scene(True), frames(with_box, 40.0)) < 0.0).any()


@pytest.mark.parametrize("yaw", [25.0, 40.0, 60.0])
def test_raised_trail_lifts_every_turned_hip_over_the_platform(yaw):
    env = scene(True)
    trail = trail_of(env)
    bf = frames(trail, yaw)
    assert (hip_clearance(env, bf) < 0.5 * HIP_CLEAR * BODY.clearance).any()
    for _ in range(2):      # as solve does: at most two raises
        raised = raised_for_hips(trail, bf, env.rays, HIPS, JOINTS, BODY.clearance, BODY.spacing)
        if raised is None:
            break
        trail = raised
        bf = frames(trail, yaw)
    gap = hip_clearance(env, bf)
    assert np.isfinite(gap).any()
    assert gap.min() >= 0.5 * HIP_CLEAR * BODY.clearance - 1e-9, gap.min()
    # raised where the platform is, not all along the trail: the joints far past it ride
    # where they did
    flat = trail_of(scene(False))
    far = (trail.points[:, 0] < 0.0) | (trail.points[:, 0] > 0.8)
    np.testing.assert_allclose(trail.points[far, 1], flat.points[far, 1], atol=1e-9)


def test_nothing_is_raised_where_every_hip_is_clear():
    """The same joints, turned, over the floor alone: no raise (a bake's trail and bytes stay
    what they were)."""
    env = scene(False)
    trail = trail_of(env)
    assert raised_for_hips(trail, frames(trail, 40.0), env.rays, HIPS, JOINTS, BODY.clearance,
                           BODY.spacing) is None


def test_a_wall_beside_the_hips_raises_nothing():
    """A hip beside a wall taller than the joint is no case for raising the body (the ray down
    from the joint's height starts inside the wall and meets no up-facing face in reach)."""
    env = env_of(floor(-0.2, 1.0, -0.3, 0.3),
                 box((0.30, 0.0, 0.45 * OFFSET), (0.34, 0.5, 0.9 * OFFSET)))
    trail = trail_of(env)
    assert raised_for_hips(trail, frames(trail, 40.0), env.rays, HIPS, JOINTS, BODY.clearance,
                           BODY.spacing) is None


def test_a_shelf_level_with_the_joints_raises_nothing():
    """A thin shelf whose edge lies between the joints and their hips, level with the joints
    (its underside just under them): the ray down from a joint's height starts inside it and
    meets its underside, which is no floor to raise the body over (it would raise the body into
    the shelf)."""
    env = env_of(floor(-0.2, 1.0, -0.3, 0.3),
                 box((0.30, 0.8 * BODY.clearance, 0.45 * OFFSET), (0.34, 1.3 * BODY.clearance, 0.9 * OFFSET)))
    trail = trail_of(env)
    assert raised_for_hips(trail, frames(trail, 40.0), env.rays, HIPS, JOINTS, BODY.clearance,
                           BODY.spacing) is None


def test_hips_inside_a_step_whose_top_is_over_the_joints_are_raised_out():
    """A step beside the path whose top is above the joints (a body crossing a step's edge
    askew, its joints over the ramp below, a hip over the top's corner): the ray down from a
    joint's height starts inside the step and missed it, the hips stayed inside it, and the
    legs from them passed through it (Godot's zdm2 arena, the 2 m rig, a crowd of 20, 9127422:
    one creature's hips inside a ridge's edge for 57 frames, 53 leg-bone hits, a leg turning
    179.6 deg in a frame). A hip inside a solid whose top is within two spacings above it now
    raises the trail; a raise or two takes every hip out of the step."""
    top = 1.4 * BODY.clearance
    env = env_of(floor(-0.2, 1.0, -0.3, 0.3),
                 box((0.30, 0.0, 0.45 * OFFSET), (0.34, top, 0.9 * OFFSET)))
    trail = trail_of(env)
    bf = frames(trail, 40.0)

    def inside():
        q = bf.rotations[:, JOINTS]
        hip = bf.positions[:, JOINTS] + quat_rotate(q, np.broadcast_to(HIPS, q.shape[:-1] + (3,)))
        return env.rays.inside(hip.reshape(-1, 3)).sum()

    assert (bf.positions[..., 1] < top).all()              # every joint under the step's top
    assert inside() > 0
    for _ in range(2):      # as solve does: at most two raises
        raised = raised_for_hips(trail, bf, env.rays, HIPS, JOINTS, BODY.clearance, BODY.spacing)
        if raised is None:
            break
        trail = raised
        bf = frames(trail, 40.0)
    assert inside() == 0
