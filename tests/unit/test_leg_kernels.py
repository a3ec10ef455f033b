"""The compiled passes of the legs and the joint-space swings (locomotion.leg_kernels) give
the same bits as the numpy forms they replace, kept here as the references: the "arc"
candidates' raise, swivel, yaw and flex (swing._Trial.pose), a leg's pose with its turn dot
products (swing._pose and quat_angle's dot), the crowding cost (swing._crowding) and a
planted leg's turns over a window and a swinging leg's over its frames (legs._stance_turns,
legs._joint_steps: two_bone_ik, _frame_steps and the knee angle), on
random poses with caps that bind and do not, zero, negative and NaN angles, missing
neighbours, feet on their hips and poles along the leg; the pose rows number poses as a dict
of their bytes would; and SIGTERMs during the direct calls stop them cleanly."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from baker.geometry.transforms import dot, length, quat_about, quat_mul, quat_rotate
from baker.locomotion import swing
from baker.locomotion import leg_kernels as sk

L1, L2 = 0.0123, 0.0171


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def unit_quats(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def numpy_arc_pose(U, T, s, prof, sin_u, cap, r, swivel, yaw, flex):
    """_Trial.pose's numpy form of the arc family after the slerp."""
    axis = np.broadcast_to(swing._Z, (len(U), 3))
    U = quat_mul(quat_about(axis, s * np.minimum(r * prof, cap)), U)
    if swivel:
        U = swing._swivel(U, T, swivel * prof, L1, L2)
    if yaw:
        U = quat_mul(quat_about(np.broadcast_to(swing._Y, (len(U), 3)), s * yaw * sin_u), U)
    if flex:
        T = swing._flex(U, T, flex * prof, L1, L2)
    return U, T


def arc_inputs(seed, n):
    rng = np.random.default_rng(seed)
    u = np.clip(rng.uniform(-0.1, 1.1, n), 0.0, 1.0)
    u[: min(n, 2)] = [0.0, 1.0][: min(n, 2)]
    side = np.where(rng.random(n) < 0.5, 1.0, -1.0)
    prof = swing.PROFILES[seed % 3](u)
    cap = np.where(rng.random(n) < 0.5, rng.uniform(0.0, 0.3, n), np.inf)
    return unit_quats(rng, n), unit_quats(rng, n), side, prof, np.sin(np.pi * u), cap


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("n", [1, 7, 64, 300])
@pytest.mark.parametrize("mods", [(0.0, 0.0, 0.0), (0.44, 0.0, 0.0), (-0.87, 0.0, 0.0),
                                  (0.0, 0.21, 0.0), (0.0, -0.42, 0.0), (0.0, 0.0, 0.35),
                                  (0.0, 0.0, 1.57), (0.44, 0.21, 0.7)])
def test_arc_pose_gives_the_numpy_forms_bits(seed, n, mods):
    U, T, side, prof, sin_u, cap = arc_inputs(seed, n)
    swivel, yaw, flex = mods
    for r in (0.0, 0.07, 1.05):
        want = numpy_arc_pose(U, T, side, prof, sin_u, cap, r, swivel, yaw, flex)
        got = sk.arc_pose(U, T, side, prof, sin_u, cap, r, swivel, yaw, flex, L1, L2)
        for g, w in zip(got, want):
            assert np.array_equal(bits(g), bits(w))


def test_arc_pose_keeps_nans_and_signed_zeros_as_numpy():
    U, T, side, prof, sin_u, cap = arc_inputs(3, 40)
    prof[5], cap[6], U[7, 2] = np.nan, np.nan, np.nan
    prof[8], cap[8] = -0.0, 0.0
    prof[9], cap[9] = 0.0, -0.0
    want = numpy_arc_pose(U, T, side, prof, sin_u, cap, 0.3, 0.44, 0.21, 0.7)
    got = sk.arc_pose(U, T, side, prof, sin_u, cap, 0.3, 0.44, 0.21, 0.7, L1, L2)
    for g, w in zip(got, want):
        assert np.array_equal(bits(g), bits(w))


def test_only_arc_candidates_swivel_yaw_or_flex():
    """_Trial.pose applies the modifiers in the arc family's kernel only."""
    for kind, _, _, swivel, flex, _, yaw in swing.CANDIDATES:
        if swivel or flex or yaw:
            assert kind.split("/")[0] == "arc", kind


def numpy_pose(q_seg, hip, U, T, l1, l2):
    """swing._pose's numpy form: world rotations of the two bones, knee and foot."""
    q_u = quat_mul(q_seg, U)
    q_t = quat_mul(q_u, T)
    mid = hip + quat_rotate(q_u, l1 * swing._Y)
    return q_u, q_t, mid, mid + quat_rotate(q_t, l2 * swing._Y)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("n", [1, 2, 63, 64, 500])
def test_leg_pose_gives_the_numpy_forms_bits(seed, n):
    rng = np.random.default_rng(seed)
    q_seg, U, T = unit_quats(rng, n), unit_quats(rng, n), unit_quats(rng, n)
    hip = rng.normal(size=(n, 3)) * 50.0
    q_u, q_t, mid, end, dots = sk.leg_pose(q_seg, hip, U, T, L1, L2)
    want = numpy_pose(q_seg, hip, U, T, L1, L2)
    for g, w in zip((q_u, q_t, mid, end), want):
        assert np.array_equal(bits(g), bits(w))
    for row, x in zip(dots, (U, T, want[0], want[1])):
        assert np.array_equal(bits(row), bits(dot(x[:-1], x[1:])))


def test_turn_faults_match_quat_angle():
    """_turn_faults from leg_pose's dots is the largest quat_angle of the four rotations."""
    rng = np.random.default_rng(5)
    n = 400

    def walk(axis):
        """Rotations turning up to 0.45 rad a step about `axis`."""
        return quat_about(np.broadcast_to(axis, (n, 3)), np.cumsum(rng.uniform(-0.45, 0.45, n)))

    q_seg = quat_mul(unit_quats(rng, 1), walk(swing._Y))
    U, T = walk(swing._Z), walk(swing._X)
    hip = rng.normal(size=(n, 3))
    q_u, q_t, _, _, dots = sk.leg_pose(q_seg, hip, U, T, L1, L2)
    same = rng.random(n - 1) < 0.8
    lim = swing.Limits(contact=0.002, slide=0.001, tol=0.001, turn=0.4, gap=0.01,
                       hard_turn=0.6)
    from baker.geometry.transforms import quat_angle

    steps = np.maximum.reduce([quat_angle(x[:-1], x[1:]) for x in (U, T, q_u, q_t)])
    want = (same & (steps > lim.turn)) + (swing.HARD - 1.0) * (same & (steps > lim.breaking_turn))
    got = swing._turn_faults(lim, dots, same)
    assert np.array_equal(bits(got), bits(want))
    assert 0 < np.count_nonzero(got == 1.0) and 0 < np.count_nonzero(got == swing.HARD)


@pytest.mark.parametrize("seed", range(6))
def test_crowding_gives_the_numpy_forms_bits(seed):
    rng = np.random.default_rng(seed)
    n = 500
    end = rng.normal(size=(n, 3)) * 0.02
    near = end[:, None] + rng.normal(size=(n, 2, 3)) * 0.01
    near[rng.random(n) < 0.2, 0] = np.nan
    near[rng.random(n) < 0.2, 1] = np.nan
    end[3] = np.nan
    inner = rng.random(n) < 0.7
    gap, hard_gap = 0.01, 0.004
    with np.errstate(invalid="ignore"):
        d = np.nanmin(length(near - end[:, None]), axis=1, initial=np.inf)
    want = inner * ((d < gap) + (swing.HARD - 1.0) * (d < hard_gap))
    got = sk.crowding(end, inner, near, gap, hard_gap, swing.HARD)
    assert np.array_equal(bits(got), bits(want))
    assert {0.0, 1.0, swing.HARD} <= set(got.tolist())


def test_rotations_are_quat_rotates():
    """The kernels' one-vector rotate is transforms.quat_rotate's (both its numpy form, below
    FUSED_ROTATE vectors, and its fused one)."""
    rng = np.random.default_rng(9)
    q = unit_quats(rng, 40)
    _, _, mid, _, _ = sk.leg_pose(q, np.zeros((40, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (40, 1)),
                                  np.tile([0.0, 0.0, 0.0, 1.0], (40, 1)), L1, L2)
    assert np.array_equal(bits(mid), bits(quat_rotate(q, L1 * swing._Y)))


def reference_rows(batches):
    """Each pose's row by a dict of its bytes: new poses numbered in the order asked."""
    seen, out = {}, []
    for hip, mid, end in batches:
        key = np.concatenate([hip, mid, end], axis=1)
        out.append(np.array([seen.setdefault(k.tobytes(), len(seen)) for k in key]))
    return out


@pytest.mark.parametrize("seed", range(4))
def test_pose_rows_tell_poses_apart_by_their_bits(seed):
    """Poses asked again (in the same batch or a later one) keep their first row; new ones
    get the next rows in order, through the table's growth and its probing; -0.0 and 0.0 are
    different poses, a NaN pose is itself."""
    rng = np.random.default_rng(seed)
    pool = rng.normal(size=(3000, 9))
    pool[1, 0], pool[2, 0] = 0.0, -0.0
    pool[2, 1:] = pool[1, 1:]
    pool[3, 4] = np.nan
    batches = []
    for size in (1, 5, 40, 300, 2000, 7, 1500):
        pick = pool[rng.integers(0, len(pool), size)]
        if size >= 5:
            pick[:5] = pool[:5]
        batches.append((pick[:, :3], pick[:, 3:6], pick[:, 6:]))
    table = sk.PoseRows()
    got = [table.rows(*b) for b in batches]
    for g, w in zip(got, reference_rows(batches)):
        assert np.array_equal(g, w)
    assert table.n == len({k.tobytes() for b in batches for k in np.concatenate(b, axis=1)})
    assert got[1][1] != got[1][2]


def numpy_stance_turns(hip, hold, fwd, left, q_inv, lay, legs, knee_out):
    """legs._stance_turns' numpy form: two_bone_ik over the window, then _frame_steps of the
    three bones and the knee angle's change."""
    from baker.geometry.ik import two_bone_ik
    from baker.geometry.transforms import cross, normalize
    from baker.locomotion.legs import _frame_steps

    target = np.broadcast_to(hold[:, None, :], hip.shape)
    u = normalize(target - hip)
    s = lay.side[legs][:, None, None]
    pole = s * cross(fwd, u) + knee_out * s * left
    sol = two_bone_ik(hip, target, pole, lay.l1, lay.l2)
    sw = (lambda a: np.swapaxes(a, 0, 1))
    m, hg = quat_rotate(q_inv, sol.mid - hip), quat_rotate(q_inv, sol.hinge)
    steps = _frame_steps(np.stack([sw(hip), sw(sol.mid), np.zeros_like(sw(m))], axis=1),
                         np.stack([sw(sol.mid), sw(sol.end), sw(m)], axis=1),
                         np.stack([sw(sol.hinge), sw(sol.hinge), sw(hg)], axis=1))
    e = quat_rotate(q_inv, sol.end - hip)
    knee = np.arccos(np.clip(dot(normalize(m), normalize(e - m)), -1.0, 1.0))
    return np.maximum(steps.max(axis=1).T, np.degrees(np.abs(np.diff(knee, axis=1))))


def stance_window(seed, n, W):
    """Planted feet near, at and beyond reach of hips that wander over a window, with some
    feet on their hip and some poles along the leg."""
    from types import SimpleNamespace

    from baker.geometry.transforms import normalize

    rng = np.random.default_rng(seed)
    lay = SimpleNamespace(side=np.array([1.0, -1.0, 1.0, -1.0]), l1=L1, l2=L2)
    legs = rng.integers(0, 4, n)
    hold = rng.normal(size=(n, 3)) * 0.01
    reach = rng.uniform(0.0, 1.3 * (L1 + L2), (n, 1, 1))
    hip = hold[:, None, :] + normalize(rng.normal(size=(n, 1, 3))) * reach
    hip = hip + np.cumsum(rng.normal(size=(n, W, 3)) * 0.002, axis=1)
    hip[0, 1] = hold[0]                                 # a foot on its hip
    fwd = normalize(rng.normal(size=(n, W, 3)))
    left = normalize(rng.normal(size=(n, W, 3)))
    fwd[1, -1] = normalize(hold[1] - hip[1, -1])        # a pole along the leg (knee_out 0)
    q_inv = quat_mul(np.broadcast_to(unit_quats(rng, n)[:, None], (n, W, 4)),
                     quat_about(np.broadcast_to(swing._Y, (n, W, 3)),
                                np.cumsum(rng.uniform(-0.3, 0.3, (n, W)), axis=1)))
    return hip, hold, fwd, left, q_inv, lay, legs


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("knee_out", [0.0, 0.35])
@pytest.mark.parametrize("W", [2, 9, 49])
def test_stance_turns_give_the_numpy_forms_bits(seed, knee_out, W):
    from baker.locomotion.legs import _stance_turns

    args = stance_window(seed, 60, W)
    with np.errstate(invalid="ignore", divide="ignore"):
        want = numpy_stance_turns(*args, knee_out)
        got = _stance_turns(*args, knee_out)
    assert got.shape == (60, W - 1)
    assert np.array_equal(bits(got), bits(want))


def test_signals_during_the_direct_compiled_calls_stop_cleanly():
    """After their first call (compiled off the main thread) the leg kernels run on the main
    thread: 100 SIGTERMs at staggered moments, each raising there, during repeated arc poses,
    leg poses, crowding, pose rows and stance traces stop them cleanly."""
    from signal_stops import assert_signals_stop_cleanly

    assert_signals_stop_cleanly("""
        import sys
        sys.path[:0] = [%r]
        from test_leg_kernels import arc_inputs, stance_window, L1, L2
        from baker.locomotion import leg_kernels as sk
        from baker.locomotion.legs import _stance_turns
        U, T, side, prof, sin_u, cap = arc_inputs(2, 3000)
        win = stance_window(1, 200, 49)
        hip = np.zeros((3000, 3))
        def calls():
            sk.arc_pose(U, T, side, prof, sin_u, cap, 0.3, 0.44, 0.21, 0.7, L1, L2)
            sk.leg_pose(U, hip, U, T, L1, L2)
            sk.crowding(hip, side > 0, np.zeros((3000, 2, 3)), 0.01, 0.004, 100.0)
            sk.PoseRows().rows(hip, hip, hip + U[:, :3])
            _stance_turns(*win, 0.35)
        calls()
    """ % str(Path(__file__).resolve().parent), """
        calls()
    """, times=100)


def numpy_joint_steps(hip, target, q_inv, fwd, left, lay, knee_out):
    """legs._joint_steps' numpy form: leg_pole and two_bone_ik over the frames, then
    _frame_steps of the three bones and the knee angle's change."""
    from baker.geometry.ik import two_bone_ik
    from baker.geometry.transforms import normalize
    from baker.locomotion.legs import _frame_steps
    from baker.rig.limbs import leg_pole

    pole = leg_pole(lay, hip, target, fwd, left, knee_out)
    sol = two_bone_ik(hip, target, pole, lay.l1, lay.l2)
    m = quat_rotate(q_inv, sol.mid - hip)
    e = quat_rotate(q_inv, sol.end - hip)
    hg = quat_rotate(q_inv, sol.hinge)
    up_step = _frame_steps(np.zeros_like(m), m, hg)
    knee = np.arccos(np.clip(dot(normalize(m), normalize(e - m)), -1.0, 1.0))
    world = np.maximum(_frame_steps(hip, sol.mid, sol.hinge),
                       _frame_steps(sol.mid, sol.end, sol.hinge))
    return np.maximum(np.maximum(up_step, np.degrees(np.abs(np.diff(knee, axis=0)))), world)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("knee_out", [0.0, 0.35])
@pytest.mark.parametrize("F", [2, 40])
def test_joint_steps_give_the_numpy_forms_bits(seed, knee_out, F):
    """Swinging feet (a target per frame) of 4 legs over F frames, some on their hips, some
    poles along the leg, some beyond reach."""
    from baker.locomotion.legs import _joint_steps

    hip, hold, fwd, left, q_inv, lay, _ = stance_window(seed, 4, F)
    rng = np.random.default_rng(seed + 100)
    hip, fwd, left, q_inv = (np.swapaxes(a, 0, 1) for a in (hip, fwd, left, q_inv))
    target = hold[None] + np.cumsum(rng.normal(size=(F, 4, 3)) * 0.004, axis=0)
    target[-1, 0] = hip[-1, 0]                          # a foot on its hip
    with np.errstate(invalid="ignore", divide="ignore"):
        want = numpy_joint_steps(hip, target, q_inv, fwd, left, lay, knee_out)
        got = _joint_steps(hip, target, q_inv, fwd, left, lay, knee_out)
    assert got.shape == (F - 1, 4)
    assert np.array_equal(bits(got), bits(want))
