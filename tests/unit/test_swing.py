"""Joint-space swings (locomotion/swing.py): a swing whose planned path breaks a limit is redone
in the leg's own joint space; stances are never touched and clean swings stay as planned."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from baker.environment.rays import RayCaster
from baker.geometry.ik import bone_frames, two_bone_ik
from baker.geometry.transforms import quat_angle, quat_conj, quat_mul
from baker.locomotion.swing import Limits, joint_space_swings

L1, L2 = 0.11, 0.12
HIP = np.array([0.03, 0.05, 0.0])


def ground() -> RayCaster:
    v = np.array([[-5, 0, -5], [5, 0, -5], [5, 0, 5], [-5, 0, 5]], float)
    return RayCaster(trimesh.Trimesh(v, [[0, 2, 1], [0, 3, 2]], process=False))


def leg(targets: np.ndarray):
    """World bone rotations, knees and feet of one left leg (hip fixed, segment unrotated)
    reaching `targets` (F, 3), knee up and out."""
    F = len(targets)
    hip = np.broadcast_to(HIP, (F, 3))
    sol = two_bone_ik(hip, targets, np.broadcast_to([0.3, 1.0, 0.0], (F, 3)), L1, L2)
    return (bone_frames(hip, sol.mid, sol.hinge), bone_frames(sol.mid, sol.end, sol.hinge),
            sol.mid, sol.end)


def run(targets, swing, lim):
    F = len(targets)
    q_u, q_t, mid, end = leg(targets)
    q_seg = np.tile([0.0, 0.0, 0.0, 1.0], (F, 1, 1))
    out = joint_space_swings(ground(), np.broadcast_to(HIP, (F, 1, 3)), q_seg, q_u[:, None],
                             q_t[:, None], mid[:, None], end[:, None], swing[:, None],
                             np.array([1.0]), L1, L2, lim)
    return out[:4], (q_u, q_t)


LIM = Limits(contact=0.004, slide=0.001, tol=0.001, turn=np.radians(27.0), gap=0.003)


def path(spike: bool):
    """15 frames: planted at A (0-4), swinging (5-9), planted at B (10-14); the swing lifts
    clear, or (spike) jumps to the far side of the hip for one frame."""
    a, b = np.array([0.17, 0.0, -0.04]), np.array([0.17, 0.0, 0.05])
    t = np.empty((15, 3))
    t[:5], t[10:] = a, b
    u = (np.arange(5, 10) - 4) / 6.0
    t[5:10] = a + (b - a) * u[:, None] + [0.0, 0.03, 0.0] * np.sin(np.pi * u)[:, None]
    if spike:
        t[7] = [0.02, 0.2, 0.0]
    swing = np.zeros(15, bool)
    swing[5:10] = True
    return t, swing


def test_a_clean_swing_stays_as_planned():
    t, swing = path(spike=False)
    (q_u, q_t, mid, end), (u0, t0) = run(t, swing, LIM)
    np.testing.assert_allclose(q_u[:, 0], u0, atol=1e-12)
    np.testing.assert_allclose(end[:, 0], t, atol=1e-9)


def test_a_snapping_swing_is_redone_within_the_turn_limit_and_stances_stay():
    t, swing = path(spike=True)
    (_, _, _, end0), (u0, t0) = run(t, swing, Limits(1e-9, 1.0, 0.0, np.pi, 0.0))
    steps0 = np.degrees(quat_angle(u0[1:], u0[:-1])).max()
    assert steps0 > 60.0                                       # the plan snaps
    (q_u, q_t, mid, end), _ = run(t, swing, LIM)
    local_t = quat_mul(quat_conj(q_u[:, 0]), q_t[:, 0])
    for q in (q_u[:, 0], local_t):
        assert np.degrees(quat_angle(q[1:], q[:-1])).max() <= 27.0 + 1e-6
    np.testing.assert_allclose(end[~swing, 0], t[~swing], atol=1e-9)     # stances untouched
    assert np.all(end[swing, 0, 1] > LIM.contact)              # the swing lifts off the floor
    assert np.all(mid[:, 0, 1] > 0.0)                          # no knee through it


def test_a_swing_while_the_body_turns_keeps_the_world_turn_within_the_limit():
    """The segment turns 20 deg a frame for three frames of a snapping swing, against the
    leg's sweep: paced only in the leg's own space, a frame's world turn (the body's turn plus
    the leg's) breaks the limit; paced by what the body's turn leaves, it does not."""
    from baker.geometry.transforms import quat_about, quat_rotate

    a, b = np.array([0.17, 0.0, -0.12]), np.array([0.17, 0.0, 0.12])
    t = np.empty((15, 3))
    t[:5], t[10:] = a, b
    u = (np.arange(5, 10) - 4) / 6.0
    t[5:10] = a + (b - a) * u[:, None] + [0.0, 0.03, 0.0] * np.sin(np.pi * u)[:, None]
    t[7] = [0.02, 0.2, 0.0]                                     # the plan snaps
    swing = np.zeros(15, bool)
    swing[5:10] = True
    yaw = -np.radians(20.0) * np.clip(np.arange(15) - 4, 0, 3)
    q_seg = quat_about(np.broadcast_to([0.0, 1.0, 0.0], (15, 3)), yaw)
    q_u, q_t, mid, end = leg(t)                                 # in the segment's frame
    hip = np.broadcast_to(HIP, (15, 3))
    out = joint_space_swings(ground(), hip[:, None], q_seg[:, None],
                             quat_mul(q_seg, q_u)[:, None], quat_mul(q_seg, q_t)[:, None],
                             (hip + quat_rotate(q_seg, mid - hip))[:, None],
                             (hip + quat_rotate(q_seg, end - hip))[:, None], swing[:, None],
                             np.array([1.0]), L1, L2, LIM)
    qu, qt = out[0][:, 0], out[1][:, 0]
    local = (quat_mul(quat_conj(q_seg), qu), quat_mul(quat_conj(qu), qt))
    for q in (qu, qt) + local:
        assert np.degrees(quat_angle(q[1:], q[:-1])).max() <= 27.0


def short_swing():
    """12 frames: planted (0-4), a swing of two frames (5-6) sweeping the leg 112 deg round its
    hip, planted (7-11). Returns (targets, swing, joint_space_swings' arguments but `lim`)."""
    a, b = np.array([0.1, 0.0, -0.15]), np.array([0.1, 0.0, 0.15])
    t = np.empty((12, 3))
    t[:5], t[7:] = a, b
    t[5:7] = a + (b - a) * np.array([1 / 3, 2 / 3])[:, None] + [0.0, 0.03, 0.0]
    swing = np.zeros(12, bool)
    swing[5:7] = True
    q_u, q_t, mid, end = leg(t)
    q_seg = np.tile([0.0, 0.0, 0.0, 1.0], (12, 1, 1))
    return t, swing, (ground(), np.broadcast_to(HIP, (12, 1, 3)), q_seg, q_u[:, None],
                      q_t[:, None], mid[:, None], end[:, None], swing[:, None], np.array([1.0]),
                      L1, L2)


def test_a_swing_too_short_to_turn_within_the_limit_lifts_off_earlier():
    """A swing of two frames that sweeps the leg 112 deg round its hip cannot keep every joint
    within 27 deg a frame; lifting off earlier (the stance before it is long) spreads the sweep
    over more frames. The touchdown frame and the stance up to the new liftoff stay."""
    t, swing, args = short_swing()
    *pose, swing2 = joint_space_swings(*args, LIM)
    lifted = np.nonzero(swing2[:, 0])[0]
    assert lifted[0] < 5 and lifted[-1] == 6                   # lifts sooner, lands as planned
    assert np.all(~swing2[:lifted[0], 0])
    qu, qt = pose[0][:, 0], pose[1][:, 0]
    local_t = quat_mul(quat_conj(qu), qt)
    for q in (qu, local_t):
        assert np.degrees(quat_angle(q[1:], q[:-1])).max() <= 27.0 + 1e-6
    np.testing.assert_allclose(pose[3][~swing2[:, 0], 0], t[~swing2[:, 0]], atol=1e-9)
    assert np.all(pose[3][swing2[:, 0], 0, 1] > 0.0)           # the swing stays above the floor


def test_faults_in_frames_that_are_not_kept_do_not_count():
    """Legs are planned over margins beyond the bake's frames (legs._planned_with_margins).
    A swing whose faults all lie in the margin is left as planned: it does not lift off
    earlier, into the kept frames (default 111304: a swing in the end margin lifted off 12
    frames sooner and crossed its neighbour's foot in the bake's last frames)."""
    from dataclasses import replace

    t, swing, args = short_swing()
    kept = np.arange(12) < 4                                    # frames 4- are a margin
    *pose, swing2 = joint_space_swings(*args, replace(LIM, judged=kept))
    assert np.array_equal(swing2[:, 0], swing)
    np.testing.assert_allclose(pose[3][:, 0], t, atol=1e-9)
    *pose, swing3 = joint_space_swings(*args, LIM)             # every frame kept: lifts sooner
    assert np.nonzero(swing3[:, 0])[0][0] < 5


def test_a_tap_between_two_swings_too_fast_for_the_limit_becomes_one_swing():
    """Two swings of two frames with a single planted frame between them (a tap: the foot lands
    at C and lifts again the next frame), sweeping the leg round its hip from A a little
    forward to C and then far forward to B. The second swing cannot keep every joint within
    27 deg a frame (52 deg before), and it cannot lift off earlier (its stance is one frame);
    solved as one swing from A to B, over the tap, every joint keeps within the limit. The
    stances before and after stay as planned."""
    a, c, b = (np.array([0.1, 0.0, z]) for z in (-0.1, -0.05, 0.16))
    t = np.empty((15, 3))
    t[:5], t[7], t[10:] = a, c, b
    t[5:7] = a + (c - a) * np.array([1 / 3, 2 / 3])[:, None] + [0.0, 0.03, 0.0]
    t[8:10] = c + (b - c) * np.array([1 / 3, 2 / 3])[:, None] + [0.0, 0.03, 0.0]
    swing = np.zeros(15, bool)
    swing[[5, 6, 8, 9]] = True
    q_u, q_t, mid, end = leg(t)
    q_seg = np.tile([0.0, 0.0, 0.0, 1.0], (15, 1, 1))
    *pose, swing2 = joint_space_swings(ground(), np.broadcast_to(HIP, (15, 1, 3)), q_seg,
                                       q_u[:, None], q_t[:, None], mid[:, None], end[:, None],
                                       swing[:, None], np.array([1.0]), L1, L2, LIM)
    assert swing2[7, 0]                                         # the tap is gone
    assert np.all(~swing2[:5, 0]) and np.all(~swing2[10:, 0])  # the stances stay
    qu, qt = pose[0][:, 0], pose[1][:, 0]
    local_t = quat_mul(quat_conj(qu), qt)
    for q in (qu, local_t):
        assert np.degrees(quat_angle(q[1:], q[:-1])).max() <= 27.0 + 1e-6
    np.testing.assert_allclose(pose[3][~swing2[:, 0], 0], t[~swing2[:, 0]], atol=1e-9)
    assert np.all(pose[3][swing2[:, 0], 0, 1] > 0.0)


def test_second_tries_merge_over_taps_and_lift_earlier_after_long_stances():
    """Which longer swing a swing that still breaks a limit tries next (frames of one leg):
    over a tap the two swings become one; after a long stance it lifts off sooner; two broken
    swings on either side of a tap share one try; a clean swing tries nothing."""
    from baker.locomotion.swing import HARD, _second_tries, _Swings

    swing = np.zeros((40, 2), bool)
    swing[10:14, 0] = swing[15:19, 0] = True      # leg 0: swings 9-14 and 14-19 (a tap at 14)
    swing[30:33, 0] = True                        # leg 0: 29-33, after a long stance
    swing[10:14, 1] = swing[15:19, 1] = True      # leg 1: the same tap, both swings broken
    sw = _Swings(swing)
    assert list(zip(sw.leg, sw.a, sw.b)) == [(0, 9, 14), (0, 14, 19), (0, 29, 33),
                                             (1, 9, 14), (1, 14, 19)]
    cost = np.array([0.5, HARD, HARD, HARD, HARD + 1.0])
    tries = _second_tries(sw, cost)
    assert tries[0] == (0, 9, 19, 0.5 + HARD)     # merged over the tap
    leg, s, e, old = tries[1]
    assert (leg, e, old) == (0, 33, HARD) and 19 + 2 <= s < 29      # lifts sooner
    leg, s, e, old = tries[2]                     # leg 1: one try over both broken swings
    assert (leg, s, e, old) == (1, 9, 19, 2 * HARD + 1.0)
    assert len(tries) == 3
    assert _second_tries(sw, np.zeros(5)) == []


@pytest.mark.parametrize("stance", [3, 4])
def test_a_swing_after_a_short_stance_merges_with_the_swing_before(stance):
    """As with a tap, but the stance between the two swings is a few frames long: lifting off
    from it sooner is impossible (3 frames) or not enough (4 frames: one frame sooner), so the
    swing that breaks the limit (52 deg a frame before) becomes one with the swing before it,
    over the stance, and every joint keeps within 27 deg a frame."""
    a, c, b = (np.array([0.1, 0.0, z]) for z in (-0.1, -0.05, 0.16))
    n = 14 + stance
    t = np.empty((n, 3))
    t[:5], t[7:7 + stance], t[9 + stance:] = a, c, b
    t[5:7] = a + (c - a) * np.array([1 / 3, 2 / 3])[:, None] + [0.0, 0.03, 0.0]
    t[7 + stance:9 + stance] = c + (b - c) * np.array([1 / 3, 2 / 3])[:, None] + [0.0, 0.03, 0.0]
    swing = np.zeros(n, bool)
    swing[[5, 6, 7 + stance, 8 + stance]] = True
    q_u, q_t, mid, end = leg(t)
    q_seg = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1, 1))
    *pose, swing2 = joint_space_swings(ground(), np.broadcast_to(HIP, (n, 1, 3)), q_seg,
                                       q_u[:, None], q_t[:, None], mid[:, None], end[:, None],
                                       swing[:, None], np.array([1.0]), L1, L2, LIM)
    assert swing2[5:9 + stance, 0].all()                        # one swing over the stance
    assert np.all(~swing2[:5, 0]) and np.all(~swing2[9 + stance:, 0])
    qu, qt = pose[0][:, 0], pose[1][:, 0]
    local_t = quat_mul(quat_conj(qu), qt)
    for q in (qu, local_t):
        assert np.degrees(quat_angle(q[1:], q[:-1])).max() <= 27.0 + 1e-6
    np.testing.assert_allclose(pose[3][~swing2[:, 0], 0], t[~swing2[:, 0]], atol=1e-9)


def test_a_swings_fastest_step_is_spread_over_the_frames_round_it_on_its_own_path():
    """_peak_spread (the "peak" candidates): two swings of 12 entries whose upper bone turns
    2 deg a frame but 40 deg in one step; with w = 3 the 40 deg step and the three entries on
    either side walk the same path at an even pace, and everything else stays."""
    from baker.geometry.transforms import quat_about
    from baker.locomotion.swing import _peak_spread

    deg = np.full(12, 2.0)
    deg[0] = 0.0
    deg[6] = 40.0                              # from entry 5 to entry 6
    ang = np.radians(np.cumsum(deg))
    U1 = quat_about(np.broadcast_to([0.0, 0.0, 1.0], (12, 3)), ang)
    U = np.concatenate([U1, U1])
    T = np.tile([0.0, 0.0, 0.0, 1.0], (24, 1))
    sid = np.repeat([0, 1], 12)
    U2, T2 = _peak_spread(U, T, sid, 3)
    steps = np.degrees(quat_angle(U2[1:], U2[:-1]))
    steps[11] = np.nan                                       # across the two swings
    win = np.arange(2, 10)                                   # entries 2..9: the steps 3..9
    for s in (0, 12):
        st = steps[s:s + 11]
        assert np.allclose(st[win[1:] - 1], (3 * 2.0 + 40.0 + 3 * 2.0) / 7.0, atol=1e-6)
        assert np.nanmax(st) < 10.0
        keep = np.setdiff1d(np.arange(12), win[1:-1]) + s    # outside the window and its ends
        np.testing.assert_allclose(U2[keep], U[keep], atol=1e-12)
    # on its own path: every new pose turns about the same axis, between its neighbours' angles
    got = 2.0 * np.degrees(np.arctan2(U2[:12, 2], U2[:12, 3]))
    assert np.all(np.diff(got) > 0.0) and np.isclose(got[-1], np.degrees(ang[-1]))
    np.testing.assert_array_equal(T2, T)


def test_the_cheapest_path_through_a_trellis_is_the_brute_force_minimum():
    """trellis.cheapest_path against every path of small random trellises."""
    import itertools

    from baker.locomotion.trellis import cheapest_path

    rng = np.random.default_rng(5)
    for _ in range(20):
        sizes = rng.integers(1, 5, size=rng.integers(2, 5))
        node = [rng.random(n) for n in sizes]
        edge = [rng.random((a, b)) for a, b in zip(sizes[:-1], sizes[1:])]

        def total(p):
            return sum(node[k][i] for k, i in enumerate(p)) + sum(
                edge[k][p[k], p[k + 1]] for k in range(len(p) - 1))

        best = min(itertools.product(*[range(n) for n in sizes]), key=total)
        pick, cost = cheapest_path(node, lambda k: edge[k])
        assert np.isclose(cost, total(best)) and np.isclose(total(tuple(pick)), cost)


def test_the_last_resort_finds_a_clear_path_over_a_wall_within_the_turn_limit():
    """_searched (the trellis search for a swing that still breaks a limit): a foot swinging
    along the floor from A to B, through a 6 cm wall between them, every bone of the middle
    frames through it. Re-chosen among sampled poses, the swing keeps every bone clear and
    every joint within 27 deg a frame; its ends stay."""
    from baker.geometry.transforms import quat_rotate
    from baker.locomotion.swing import _searched

    box = trimesh.creation.box(extents=[0.2, 0.06, 0.03])
    box.apply_translation([0.2, 0.03, 0.0])
    env = trimesh.util.concatenate([ground().mesh, box])
    rays = RayCaster(trimesh.Trimesh(env.vertices, env.faces, process=False))
    u = np.linspace(0.0, 1.0, 8)
    t = np.array([0.17, 0.0, -0.08]) + np.outer(u, [0.0, 0.0, 0.16])
    q_u, q_t, mid, end = leg(t)
    hip = np.broadcast_to(HIP, (8, 3))
    q_seg = np.tile([0.0, 0.0, 0.0, 1.0], (8, 1))
    U, T = q_u, quat_mul(quat_conj(q_u), q_t)
    hit = rays.first_hit(mid, end - mid, max_distance=L2 - LIM.tol).hit
    assert hit[1:-1].any()                                    # the floor path meets the wall
    near = np.full((8, 2, 3), np.nan)
    U2, T2 = _searched(rays, LIM, hip, q_seg, U, T, near, np.ones(8), 1.0, L1, L2, 0, 7)
    qu2, qt2 = U2, quat_mul(U2, T2)
    knee = hip + quat_rotate(qu2, L1 * np.array([0.0, 1.0, 0.0]))
    foot = knee + quat_rotate(qt2, L2 * np.array([0.0, 1.0, 0.0]))
    assert not rays.first_hit(hip, knee - hip, max_distance=L1 - 1e-9).hit.any()
    assert not rays.first_hit(knee, foot - knee, max_distance=L2 - LIM.tol).hit.any()
    for q in (U2, T2, qu2, qt2):
        assert np.degrees(quat_angle(q[1:], q[:-1])).max() <= 27.0
    np.testing.assert_array_equal(U2[[0, -1]], U[[0, -1]])
    np.testing.assert_array_equal(T2[[0, -1]], T[[0, -1]])
