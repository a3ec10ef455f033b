"""A swinging foot whose leg would pass through something is drawn toward its hip
(legs._pull_in_swings), eased in the knee's bend: near a straight knee a small change of reach
bends the knee a lot, so a pull eased in distance (10% of it per frame, the code before) bent a
nearly straight leg by 27 degrees in one frame here, and 32 degrees on a multi-storey bake.

One leg, 0.22 + 0.24 m, its hip still, its foot held 0.44 m out (the knee 36 degrees from
straight) inside a box for a 40-frame swing, planted at both ends."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import trimesh

from baker.environment.rays import RayCaster
from baker.geometry.ik import two_bone_ik
from baker.locomotion.legs import PULL_BEND_RATE, _knee_bend, _leg_blocked, _pull_in_swings
from test_navmesh_scenes import box

L1, L2, TOL = 0.22, 0.24, 0.001
F = 40
LAY = SimpleNamespace(l1=L1, l2=L2, side=np.array([1.0]))
FWD = np.broadcast_to([0.0, 0.0, 1.0], (F, 1, 3))
LEFT = np.broadcast_to([1.0, 0.0, 0.0], (F, 1, 3))
KNEE_OUT = 0.3


def scene():
    rays = RayCaster(box((0.40, 0.12, -0.2), (0.60, 0.28, 0.2)))     # round the foot
    hip = np.broadcast_to([0.0, 0.2, 0.0], (F, 1, 3)).copy()
    target = np.broadcast_to([0.44, 0.2, 0.0], (F, 1, 3)).copy()
    sw = np.ones((F, 1), bool)
    sw[[0, -1]] = False
    return rays, hip, target, sw


def blocked(rays, hip, target):
    n = len(hip)
    return _leg_blocked(rays, LAY, np.zeros(n, int), hip.reshape(-1, 3), target.reshape(-1, 3),
                        FWD.reshape(-1, 3)[:n], LEFT.reshape(-1, 3)[:n], KNEE_OUT, TOL)


def bends(hip, target):
    d = two_bone_ik(hip, target, np.broadcast_to([0.0, 1.0, 0.0], hip.shape), L1, L2).reach
    return np.degrees(_knee_bend(d[:, 0], L1, L2))


def test_the_pull_clears_the_leg_and_bends_the_knee_gently():
    rays, hip, target, sw = scene()
    assert blocked(rays, hip, target).all()
    out = _pull_in_swings(rays, hip, target, sw, FWD, LEFT, LAY, KNEE_OUT, TOL)
    b = bends(hip, out)
    assert abs(b[0] - bends(hip, target)[0]) < 1e-9          # planted ends untouched
    assert np.allclose(out[[0, -1]], target[[0, -1]])
    steps = np.abs(np.diff(b))
    assert steps.max() <= np.degrees(PULL_BEND_RATE) + 1e-6
    assert steps.max() > 0.5 * np.degrees(PULL_BEND_RATE)    # it did pull
    # the middle of the swing, where the pull has had time to grow, is clear of the box
    assert not blocked(rays, hip[10:30], out[10:30]).any()
    # the foot is only drawn in along the hip -> foot line
    rel = out - hip
    assert np.allclose(rel[..., 1:], 0.0) and np.all(rel[..., 0] <= 0.44 + 1e-12)


def test_an_unblocked_swing_is_left_alone():
    rays, hip, target, sw = scene()
    target[..., 0] = 0.3
    assert not blocked(rays, hip, target).any()
    out = _pull_in_swings(rays, hip, target, sw, FWD, LEFT, LAY, KNEE_OUT, TOL)
    assert np.array_equal(out, target)
