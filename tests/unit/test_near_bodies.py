"""A crowd's ultimate legs and antennae clear the other creatures' bodies they reach
(locomotion.near.crowd_near, solve.solve.solve_limbs): an ultimate leg trails 4.4 spacings behind the tail, and
a tail swinging round a fold of its trail swept one 1 mm into a resting neighbour's head in a
100-creature minute (the crowd check: no leg bone within a body radius of another creature's
spine segments)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from baker.config import DEFAULT_RIG, load_rig_config
from baker.geometry.proximity import segment_distances
from baker.locomotion.body import body_frames, build_trail
from baker.locomotion.legs import leg_frames
from baker.locomotion.near import CrowdSpines, NearBodies, crowd_near, near_bodies
from baker.metrics import leg_bones
from test_navmesh_scenes import env_of, quad

RIG = load_rig_config(DEFAULT_RIG)
RADIUS = float(max(RIG.body.width_profile))
F = 40


def walker():
    """(environment, BodyFrames, head arcs, times) of a body walking slowly up +X on the flat."""
    b = RIG.body
    env = env_of(quad((-1, 0, -1), (-1, 0, 1), (1, 0, 1), (1, 0, -1)))
    path = np.column_stack([np.linspace(-0.6, 0.2, 800), np.zeros((800, 2))])
    trail = build_trail(path, env.rays, probe=0.1, spacing=b.spacing, clearance=b.clearance)
    head_arc = trail.arc_at(np.linspace(0.5, 0.5 + 0.002 * F, F))
    bf = body_frames(trail, head_arc, b.spacing, b.segments, b.clearance, fps=30)
    return env, bf, head_arc, np.arange(F) / 30.0


def ultimate_bones(lf):
    traj = SimpleNamespace(joint_names=lf.names, joint_positions=lf.positions,
                           joint_rotations=lf.rotations, n_frames=F)
    a, b, names = leg_bones(traj, RIG.legs)
    keep = [k for k, n in enumerate(names) if n.startswith("ultimate_")]
    return a[:, keep], b[:, keep]


def closest(a, b, other):
    """(F,) the closest of bones a-b (F, B, 3) to the spine segments of `other` (F, S, 3)."""
    B, M = a.shape[1], other.shape[1] - 1
    shape = (F, B, M, 3)
    d = segment_distances(*(np.broadcast_to(x, shape).reshape(-1, 3) for x in
                            (a[:, :, None], b[:, :, None], other[:, None, :-1],
                             other[:, None, 1:])))
    return d.reshape(F, B, M).min(axis=(1, 2))


def test_ultimate_legs_rise_clear_of_a_body_lying_across_them():
    env, bf, head_arc, times = walker()
    alone = leg_frames(bf, head_arc, times, env.rays, RIG)
    a, b = ultimate_bones(alone)
    # another creature resting across the left ultimate leg's tip, at its height
    tip = b[0, 0]
    z = tip[2] + RIG.body.spacing * np.arange(-10, 11)
    other = np.broadcast_to(np.column_stack([np.full(21, tip[0]), np.full(21, tip[1]), z]),
                            (F, 21, 3))
    assert closest(a, b, other).min() < 0.5 * RADIUS          # alone, it lies through it
    spines = np.stack([bf.positions, other])
    near = crowd_near(env.rays, CrowdSpines(spines), 0, RIG)
    assert isinstance(near, NearBodies)
    lf = leg_frames(bf, head_arc, times, env.rays, RIG, near=near)
    a, b = ultimate_bones(lf)
    assert closest(a, b, other).min() >= RADIUS
    # the walking legs and the spine are as they were
    walking = [k for k, n in enumerate(lf.names) if n.startswith("leg_")]
    assert np.array_equal(lf.positions[:, walking], alone.positions[:, walking])


def test_far_bodies_are_not_near_and_change_nothing():
    env, bf, head_arc, times = walker()
    far = bf.positions + np.array([0.0, 0.0, 0.5])
    assert crowd_near(env.rays, CrowdSpines(np.stack([bf.positions, far])), 0, RIG) is None


def test_near_bodies_keeps_each_frames_segments_within_reach():
    # two frames: the other body's joints 0.05 and 0.5 from the base
    spines = np.zeros((2, 2, 3, 3))
    spines[1, 0] = [[0.05, 0, 0], [0.06, 0, 0], [0.07, 0, 0]]
    spines[1, 1] = [[0.5, 0, 0], [0.51, 0, 0], [0.52, 0, 0]]
    bases = np.zeros((2, 1, 3))
    near = near_bodies(None, CrowdSpines(spines), 0, bases, reach=0.1, radius=0.01)
    assert near.a.shape == (2, 2, 3)
    assert np.isfinite(near.a[0]).all() and np.isnan(near.a[1]).all()
    # a bone along x from the origin touches frame 0's segments only
    p = np.zeros((2, 3))
    q = np.array([[0.1, 0.0, 0.0], [0.1, 0.0, 0.0]])
    assert near.touches(p, q).tolist() == [True, False]
    assert near.at(np.array([1])).touches(p[:1], q[:1]).tolist() == [False]


def test_touches_is_the_numpy_distance_test_pair_by_pair():
    """NearBodies.touches (compiled, stopping at a bone's first touch) answers what the
    numpy segment distances say: random bones against random segments, with zero-length
    bones and segments, parallel pairs, and NaN slots (no segment there) among them."""
    rng = np.random.default_rng(11)
    R, K, M, radius = 40, 7, 9, 0.05
    p = rng.uniform(-0.2, 0.2, (R, K, 3))
    q = p + rng.uniform(-0.15, 0.15, (R, K, 3))
    a = rng.uniform(-0.2, 0.2, (R, M, 3))
    b = a + rng.uniform(-0.15, 0.15, (R, M, 3))
    q[:, 0] = p[:, 0]                                   # zero-length bones
    b[:, 1] = a[:, 1]                                   # zero-length segments
    b[:, 2] = a[:, 2] + (q[:, 1] - p[:, 1])             # parallel to bone 1
    a[::3, 5:], b[::3, 5:] = np.nan, np.nan             # rows with fewer segments
    a[7], b[7] = np.nan, np.nan                         # a row with none
    near = NearBodies(None, a, b, radius)
    got = near.touches(p, q)
    shape = (R, K, M, 3)
    d = segment_distances(*(np.broadcast_to(x, shape).reshape(-1, 3) for x in
                            (p[:, :, None], q[:, :, None], a[:, None], b[:, None])))
    want = (np.nan_to_num(d, nan=np.inf) < radius).reshape(R, K, M).any(axis=2)
    assert got.shape == (R, K) and 0.2 < want.mean() < 0.8
    assert np.array_equal(got, want)
    assert not got[7].any()
