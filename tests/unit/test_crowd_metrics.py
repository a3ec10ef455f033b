"""The crowd's inter-creature checks (metrics.crowd_metrics): segment-to-segment distances
against a dense search, the smallest spine gap against all pairs, leg bones inside other
bodies on creatures placed by hand, and five spine-only creatures on a small plane."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from baker.config import DEFAULT_RIG, BakeConfig, load_rig_config
from baker.context import Context
from baker.geometry.proximity import segment_distances
from baker.metrics import crowd_metrics, leg_bones, legs_through_others, min_spine_gap
from baker.solve.trajectory import Trajectory

RIG = load_rig_config(DEFAULT_RIG)
RADIUS = max(RIG.body.width_profile)


def point_segment(x, a, b) -> float:
    d = b - a
    t = 0.0 if d @ d < 1e-18 else float(np.clip((x - a) @ d / (d @ d), 0.0, 1.0))
    return float(np.linalg.norm(a + t * d - x))


def reference_distance(p1, q1, p2, q2) -> float:
    """The closest distance of two segments, one pair at a time: on the boundary of the
    parameter square (an end point against the other segment) or at the lines' interior
    closest pair when it lies inside both segments."""
    best = min(point_segment(p1, p2, q2), point_segment(q1, p2, q2),
               point_segment(p2, p1, q1), point_segment(q2, p1, q1))
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    m = np.array([[d1 @ d1, -(d1 @ d2)], [-(d1 @ d2), d2 @ d2]])
    if abs(np.linalg.det(m)) > 1e-12:
        s, t = np.linalg.solve(m, [-(d1 @ r), d2 @ r])
        if 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0:
            best = min(best, float(np.linalg.norm(p1 + s * d1 - p2 - t * d2)))
    return best


def test_segment_distances_match_a_pairwise_reference():
    rng = np.random.default_rng(3)
    m = 2000
    p1, q1, p2, q2 = (rng.normal(size=(m, 3)) for _ in range(4))
    q1[:20] = p1[:20]                                   # points, not segments
    q2[10:30] = p2[10:30]
    q2[40:60] = p2[40:60] + 2.0 * (q1[40:60] - p1[40:60])   # parallel segments
    d = segment_distances(p1, q1, p2, q2)
    ref = [reference_distance(p1[k], q1[k], p2[k], q2[k]) for k in range(m)]
    np.testing.assert_allclose(d, ref, atol=1e-9)


def test_min_spine_gap_is_the_smallest_pair_of_different_creatures():
    rng = np.random.default_rng(5)
    spines = rng.uniform(-1.0, 1.0, size=(4, 30, 21, 3))
    got = min_spine_gap(spines)
    best = (np.inf, -1, None)
    own = np.repeat(np.arange(4), 21)
    for f in range(30):
        d = cdist(spines[:, f].reshape(-1, 3), spines[:, f].reshape(-1, 3))
        d[own[:, None] == own[None, :]] = np.inf
        k = np.unravel_index(np.argmin(d), d.shape)
        if d[k] < best[0]:
            best = (d[k], f, sorted([own[k[0]], own[k[1]]]))
    assert got["gap_m"] == pytest.approx(best[0], abs=1e-12)
    assert got["frame"] == best[1] and got["creatures"] == best[2]
    assert min_spine_gap(spines[:1])["gap_m"] == np.inf


def straight(x: float, F: int = 3, z0: float = 0.0, names=("leg_L_01_upper", "leg_L_01_tip"),
             leg=None) -> Trajectory:
    """A creature lying along +Z at x (21 spine joints 0.0125 m apart, head at z0), with one
    leg whose upper bone runs from `leg[0]` to `leg[1]` (default: 0.02 m toward +X from the
    head) and whose tip bone points down (local +Y rotated to -Y) by the rig's tip length."""
    S = 21
    sp = np.zeros((F, S, 3))
    sp[..., 0] = x
    sp[..., 2] = z0 - 0.0125 * np.arange(S)
    rot = np.tile([0.0, 0.0, 0.0, 1.0], (F, S, 1))
    a, b = (np.array([x, 0.0, z0]), np.array([x + 0.02, 0.0, z0])) if leg is None else leg
    jp = np.tile(np.stack([a, b]), (F, 1, 1)).astype(float)
    jr = np.tile([[0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0]], (F, 1, 1))  # tip: 180 deg on X
    return Trajectory(times=np.arange(F) / 30.0, spine_positions=sp, spine_rotations=rot,
                      head_surface_normal=np.tile([0.0, 1.0, 0.0], (F, 1)),
                      ground_heights=np.zeros((F, S)), joint_names=tuple(names),
                      joint_positions=jp, joint_rotations=jr)


def test_leg_bones_upper_and_tip():
    t = straight(0.0, leg=(np.array([0.0, 0.01, 0.0]), np.array([0.02, 0.01, 0.0])))
    a, b, names = leg_bones(t, RIG.legs)
    assert names == ["leg_L_01_upper", "leg_L_01_tip"]
    np.testing.assert_allclose(a[0], [[0.0, 0.01, 0.0], [0.02, 0.01, 0.0]])
    np.testing.assert_allclose(b[0, 1], [0.02, 0.01 - RIG.legs.tip_length, 0.0], atol=1e-12)


def test_a_leg_through_another_body_is_counted():
    # creature 0's leg reaches across creature 1's spine (x = 0.05) at z = -0.1
    reach = (np.array([0.01, 0.005, -0.1]), np.array([0.07, 0.005, -0.1]))
    trajs = [straight(0.0, leg=reach), straight(0.05)]
    out = legs_through_others(trajs, RIG.legs, RADIUS)
    assert out["bone_frames"] == 3 and out["frames"] == 3           # the upper bone, 3 frames
    assert out["by_creature"] == [3, 0]
    assert out["deepest_m"] == pytest.approx(0.005, abs=1e-9)
    # moved clear of it: nothing
    clear = (np.array([0.01, 0.05, -0.1]), np.array([0.07, 0.05, -0.1]))
    out = legs_through_others([straight(0.0, leg=clear), straight(0.05)], RIG.legs, RADIUS)
    assert out["bone_frames"] == 0 and out["deepest_m"] is None
    # its own body never counts
    own = (np.array([-0.02, 0.0, -0.1]), np.array([0.02, 0.0, -0.1]))
    assert legs_through_others([straight(0.0, leg=own), straight(1.0)], RIG.legs,
                               RADIUS)["bone_frames"] == 0


def test_crowd_metrics_of_creatures_side_by_side():
    trajs = [straight(0.0), straight(0.03), straight(0.5)]
    m = crowd_metrics(trajs, RIG.legs, RADIUS)
    assert m["creatures"] == 3 and m["min_spine_gap_m"] == pytest.approx(0.03)
    assert m["min_spine_gap_creatures"] == [0, 1]
    assert m["spines_apart"] == (0.03 >= 2 * RADIUS)
    # creature 0's upper bone (x 0..0.02) ends, and its tip bone starts, 0.01 from creature 1's
    # head, inside its radius: two bones in 3 frames; creature 1's leg points away
    assert m["leg_bones_in_other_bodies_by_creature"] == [6, 0, 0]
    assert m["leg_bones_in_other_bodies_frames"] == 3


def test_five_creatures_on_a_small_plane_keep_their_spines_apart():
    from test_crowd import env_of, floor, nav_of
    from baker.sim.loop import simulate_crowd

    env = env_of(floor(-1.0, 1.0, -1.0, 1.0))
    rig = replace(RIG, legs=replace(RIG.legs, enabled=False))
    cfg = BakeConfig(seconds=6.0, prey=0, rig=rig, behaviour="wander")
    trajs = simulate_crowd(cfg, env, nav_of(env), 3, 5, Context())
    m = crowd_metrics(trajs, rig.legs, RADIUS)
    assert m["spines_apart"] and m["min_spine_gap_m"] >= 2.0 * RADIUS
    assert m["min_spine_gap_m"] < 0.5          # on a 2 m plane they do come near each other
    assert m["leg_bones_in_other_bodies"] == 0


def test_cross_pairs_are_one_search_of_all_creatures_less_their_own_pairs():
    """_cross_pairs finds the pairs one k-d search of every creature's bones and segments
    (_frame_space) finds, less each creature's own: the same (i, j) set."""
    from scipy.spatial import cKDTree

    from baker.metrics import _cross_pairs, _frame_space

    rng = np.random.default_rng(3)
    fc, n, B, M, f0, far, reach = 4, 6, 5, 3, 7, 50.0, 0.08
    path = rng.uniform(-0.2, 0.2, (1, n, 1, 3)) + np.linspace(0.0, 0.1, fc)[:, None, None, None]
    bones = path + rng.normal(0.0, 0.05, (fc, n, B, 3))
    segs = path + rng.normal(0.0, 0.05, (fc, n, M, 3))
    i, j = _cross_pairs(bones, segs, f0, far, reach)
    found = cKDTree(_frame_space(bones.reshape(fc, n * B, 3), f0, far)).sparse_distance_matrix(
        cKDTree(_frame_space(segs.reshape(fc, n * M, 3), f0, far)), reach, output_type="ndarray")
    ai, aj = found["i"].astype(np.int64), found["j"].astype(np.int64)
    other = (ai % (n * B)) // B != (aj % (n * M)) // M
    assert len(i) > 0 and (ai // (n * B) == aj // (n * M)).all()
    assert sorted(zip(i.tolist(), j.tolist())) == sorted(zip(ai[other].tolist(),
                                                             aj[other].tolist()))
